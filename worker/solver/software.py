"""What software a result was made with: the versions of every library whose version can change
an answer, and this project's version and source revision. Read once per process."""

from __future__ import annotations

import functools
import subprocess
from importlib import metadata
from pathlib import Path

PROJECT = "entry-trajopt"

LIBRARIES = (
    "numpy",
    "scipy",
    "clarabel",
    "piqp",
    "cvxpy",
    "ecos",
    "scs",
    "numba",
    "llvmlite",
    "ussa1976",
    "xarray",
    "pymoo",
    "pydantic",
    PROJECT,
)
"""The arithmetic (numpy, scipy), the conic solvers and their modelling layer (clarabel, piqp,
cvxpy and its fallbacks ecos, scs), the compiled kernels (numba on llvmlite), the US76 atmosphere
(ussa1976 on xarray), the global search (pymoo), the contract's defaults (pydantic) and this
project."""

GIT_DESCRIBE = ("git", "describe", "--always", "--dirty", "--abbrev=40", "--exclude=*")
"""The full commit hash (no tag names) and ``-dirty`` when tracked files changed."""

_CHECKOUT = Path(__file__).resolve().parents[2]
"""The folder holding the ``worker`` package: a git checkout when run from one."""


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


@functools.cache
def _library_versions() -> tuple[tuple[str, str | None], ...]:
    return tuple((name, _version(name)) for name in LIBRARIES)


def library_versions() -> dict[str, str | None]:
    """The installed version of each of :data:`LIBRARIES` (None: not installed), read once."""
    return dict(_library_versions())


@functools.cache
def source_revision() -> str | None:
    """The git commit the code runs from (``-dirty`` with uncommitted changes to tracked
    files), or None when it does not run from a git checkout or git cannot tell; never
    raises."""
    if not (_CHECKOUT / ".git").exists():  # an installed package: no checkout of its own
        return None
    try:
        done = subprocess.run(
            [*GIT_DESCRIBE[:1], "-C", str(_CHECKOUT), *GIT_DESCRIBE[1:]],
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    revision = done.stdout.strip()
    return revision if done.returncode == 0 and revision else None


def software() -> dict[str, str | None]:
    """This project's name, version and source revision, read once."""
    return {
        "name": PROJECT,
        "version": dict(_library_versions())[PROJECT],
        "revision": source_revision(),
    }
