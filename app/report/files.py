"""``trajopt plot``: every plot of a result document file written to a directory."""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from app.report.plots import PLOT_FORMATS, available_plots, render_plot


def read_result(path: str) -> dict[str, Any]:
    """The result document in file ``path``; ValueError with a one-line reason otherwise."""
    from worker.solver.cli import InputError, read_json_file

    try:
        document = read_json_file(path, "a result file")
    except InputError as exc:
        raise ValueError(str(exc)) from None
    if not isinstance(document, Mapping) or "status" not in document:
        raise ValueError(
            f"{path} is not a result document (no status; trajopt solve -o writes one)"
        )
    return dict(document)


def write_plots(
    result: Mapping[str, Any],
    directory: Path,
    formats: Sequence[str],
    only: Sequence[str] | None = None,
) -> list[Path]:
    """Render each available plot (or those of ``only``) of ``result`` in each format into
    ``directory`` (made if missing) as ``NAME.FORMAT``; the files written."""
    names = available_plots(result)
    if only:
        unknown = [name for name in only if name not in names]
        if unknown:
            listed = ", ".join(names) or "none"
            raise ValueError(f"no plot {', '.join(unknown)} in this result; its plots: {listed}")
        names = [name for name in names if name in only]
    bad = [fmt for fmt in formats if fmt not in PLOT_FORMATS]
    if bad:
        raise ValueError(f"unknown format {', '.join(bad)}; formats: {', '.join(PLOT_FORMATS)}")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {directory}: {exc.strerror}") from None
    written = []
    for name in names:
        for fmt in dict.fromkeys(formats):
            path = directory / f"{name}.{fmt}"
            try:
                path.write_bytes(render_plot(result, name, fmt))
            except OSError as exc:
                raise ValueError(f"cannot write {path}: {exc.strerror}") from None
            written.append(path)
    return written


def plot_command(
    source: str, output: str, formats: Sequence[str], only: Sequence[str] | None
) -> int:
    """Write the plots of result file ``source`` to directory ``output``; exit code 0 (1 when the
    result has nothing to plot). Bad input raises ValueError with one line."""
    result = read_result(source)
    written = write_plots(result, Path(output), formats, only)
    for path in written:
        print(path)
    if not written:
        print(f"{source} has no trajectory and no history: nothing to plot", file=sys.stderr)
        return 1
    return 0
