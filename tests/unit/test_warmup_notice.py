"""The warm-up tells its caller why it waits: "compiling" at once when numba's on-disk cache lacks
the kernels, "loading" when a load from the cache is slow (a machine under load), nothing when
the load is quick or the kernels are loaded already. Whether the cache holds the kernels is read
from numba's cache index, not guessed from the time the warm-up takes."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.integration.harness import REPO_ROOT, service_free_env
from worker.solver import warmup


def test_a_compile_is_announced_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", False)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 60.0)
    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)
    monkeypatch.setattr(warmup, "_load_kernels", lambda: 0.0)
    heard: list[str] = []
    warmup.warm_up(heard.append)
    assert heard == ["compiling"]


def test_a_slow_load_from_the_filled_cache_says_loading(monkeypatch: pytest.MonkeyPatch) -> None:
    """The cache this suite runs with is filled (``python -m worker.solver.warmup`` first): a
    warm-up that is slow, as on a machine under load, loads; it does not compile."""
    warmup.warm_up()  # the kernels are in numba's cache (compiled here if they were not)
    monkeypatch.setattr(warmup, "_warmed", False)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.05)
    monkeypatch.setattr(warmup, "_load_kernels", lambda: time.sleep(0.3) or 0.3)
    heard: list[str] = []
    warmup.warm_up(heard.append)
    assert heard == ["loading"]


def test_a_fast_load_stays_silent(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", False)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.2)
    monkeypatch.setattr(warmup, "kernels_cached", lambda: True)
    monkeypatch.setattr(warmup, "_load_kernels", lambda: 0.0)
    heard: list[str] = []
    warmup.warm_up(heard.append)
    time.sleep(0.3)  # a timer that was not cancelled would have fired by now
    assert heard == []


def test_loaded_kernels_return_at_once_without_notice(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "_warmed", True)
    monkeypatch.setattr(warmup, "NOTICE_AFTER_S", 0.0)
    heard: list[str] = []
    assert warmup.warm_up(heard.append) == 0.0
    time.sleep(0.05)
    assert heard == []


def _cached_in(cache: Path | None) -> str:
    """What a fresh process says of numba's cache (``cache``: its folder; None: the default)."""
    env = service_free_env()
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    done = subprocess.run(
        [sys.executable, "-c", "from worker.solver import warmup; print(warmup.kernels_cached())"],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return done.stdout.strip()


@pytest.mark.slow
def test_a_fresh_process_reads_the_cache_state_without_compiling(tmp_path: Path) -> None:
    """An empty cache folder stands for a fresh install: nothing is cached there; the suite's
    own cache is filled. Neither answer compiles anything (no index or code lands in the empty
    folder; numba only makes its sub-folders)."""
    warmup.warm_up()
    assert _cached_in(None) == "True"
    assert _cached_in(tmp_path) == "False"
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


def test_quiet_keeps_the_compile_notice_and_drops_the_slow_load_notice(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A minute of compiling is said even with --quiet (silence would read as a hang); a slow
    load from the cache is progress chatter that --quiet leaves out."""
    from worker.solver.cli import _kernels_notice

    _kernels_notice("loading", quiet=True)
    assert capsys.readouterr().err == ""
    _kernels_notice("loading")
    assert "loading the solver's compiled kernels" in capsys.readouterr().err
    _kernels_notice("compiling", quiet=True)
    assert "compiling the solver's kernels" in capsys.readouterr().err
