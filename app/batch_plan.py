"""The children of a batch: the base problem document with each child's parameter values set at
their JSON pointers (a grid's combinations, a Monte Carlo draw, or another method). Pure logic:
no database, no validation of the children (the submission does that, child by child)."""

from __future__ import annotations

import copy
import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.schemas.batch import BatchRequest, Dispersion


class PointerError(ValueError):
    """A JSON pointer that does not name a member of the document (the message says where)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.pointer = message.split(":", 1)[0]


@dataclass(frozen=True)
class Child:
    """One child of a batch: its position, what was set and the resulting problem document."""

    index: int
    parameters: dict[str, Any]
    """JSON pointer -> value for grids and Monte Carlo; ``{"/method": {...}}`` for methods."""
    document: dict[str, Any]


def pointer_tokens(pointer: str) -> list[str]:
    """The reference tokens of a JSON pointer (RFC 6901: ``~1`` is ``/``, ``~0`` is ``~``)."""
    return [t.replace("~1", "/").replace("~0", "~") for t in pointer.split("/")[1:]]


def _step(node: Any, token: str, pointer: str) -> Any:
    if isinstance(node, dict):
        if token not in node:
            raise PointerError(f"{pointer}: the document has no member {token!r} there")
        return node[token]
    if isinstance(node, list):
        if not token.isdigit() or int(token) >= len(node):
            raise PointerError(f"{pointer}: no item {token!r} in a list of {len(node)}")
        return node[int(token)]
    raise PointerError(f"{pointer}: {token!r} is below a {type(node).__name__}, not an object")


def get_at(document: Any, pointer: str) -> Any:
    """The member of ``document`` at ``pointer``."""
    node = document
    for token in pointer_tokens(pointer):
        node = _step(node, token, pointer)
    return node


def set_at(document: Any, pointer: str, value: Any) -> None:
    """Set the member at ``pointer`` (its parent must exist; an object may gain the member,
    a list item must exist)."""
    *parents, last = pointer_tokens(pointer)
    node = document
    for token in parents:
        node = _step(node, token, pointer)
    if isinstance(node, dict):
        node[last] = value
    elif isinstance(node, list):
        _step(node, last, pointer)
        node[int(last)] = value
    else:
        raise PointerError(f"{pointer}: the parent is a {type(node).__name__}, not an object")


def batch_size(request: BatchRequest) -> int:
    """How many children the request makes (known before any is built)."""
    if request.grid is not None:
        return math.prod(len(p.values) for p in request.grid.parameters)
    if request.monte_carlo is not None:
        return request.monte_carlo.samples
    if request.footprint is not None:
        return len(request.footprint.longitudes_deg) * len(request.footprint.extremes)
    return len(request.methods or [])


def _draw(rng: np.random.Generator, dispersion: Dispersion, base_value: float) -> float:
    """One value of ``dispersion`` around the base document's ``base_value``."""
    if dispersion.distribution == "normal":
        mean = base_value if dispersion.mean is None else dispersion.mean
        assert dispersion.sigma is not None  # the schema requires it
        return float(rng.normal(mean, dispersion.sigma))
    if dispersion.half_width is not None:
        low, high = base_value - dispersion.half_width, base_value + dispersion.half_width
    else:
        assert dispersion.low is not None and dispersion.high is not None
        low, high = dispersion.low, dispersion.high
    return float(rng.uniform(low, high))


def _number_at(document: dict[str, Any], pointer: str) -> float:
    value = get_at(document, pointer)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise PointerError(f"{pointer}: a dispersion needs a number there, the base has {value!r}")
    return float(value)


def expand(request: BatchRequest, base: dict[str, Any]) -> list[Child]:
    """The children of ``request`` on the (validated, defaults filled) ``base`` document, in
    order; PointerError when a path does not fit the base document."""
    children: list[Child] = []
    if request.grid is not None:
        paths = [p.path for p in request.grid.parameters]
        combinations = itertools.product(*(p.values for p in request.grid.parameters))
        for index, values in enumerate(combinations):
            document = copy.deepcopy(base)
            for path, value in zip(paths, values, strict=True):
                set_at(document, path, copy.deepcopy(value))
            children.append(Child(index, dict(zip(paths, values, strict=True)), document))
    elif request.monte_carlo is not None:
        spec = request.monte_carlo
        centres = [_number_at(base, d.path) for d in spec.dispersions]
        rng = np.random.default_rng(spec.seed)
        for index in range(spec.samples):
            document = copy.deepcopy(base)
            drawn = {}
            for dispersion, centre in zip(spec.dispersions, centres, strict=True):
                value = _draw(rng, dispersion, centre)
                set_at(document, dispersion.path, value)
                drawn[dispersion.path] = value
            children.append(Child(index, drawn, document))
    elif request.footprint is not None:
        sweep = request.footprint
        edges = [(lon, edge) for lon in sweep.longitudes_deg for edge in sweep.extremes]
        for index, (longitude, edge) in enumerate(edges):
            document = copy.deepcopy(base)
            set_at(document, "/terminal/longitude_deg", longitude)
            set_at(document, "/terminal/latitude_deg", {"kind": "free"})
            document["objective"] = edge
            children.append(
                Child(index, {"/terminal/longitude_deg": longitude, "/objective": edge}, document)
            )
    else:
        for index, method in enumerate(request.methods or []):
            document = copy.deepcopy(base)
            document["method"] = copy.deepcopy(method)
            children.append(Child(index, {"/method": method}, document))
    return children


def parameter_distance(a: dict[str, Any], b: dict[str, Any]) -> float:
    """How far two children's parameters are: the root of the summed squared relative
    differences of the numbers; infinite when another parameter (a method, an objective, a
    non-number) differs."""
    total = 0.0
    for path in a.keys() | b.keys():
        x, y = a.get(path), b.get(path)
        numbers = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (x, y))
        if numbers:
            assert isinstance(x, int | float) and isinstance(y, int | float)
            scale = max(abs(x), abs(y), 1e-12)
            total += ((x - y) / scale) ** 2
        elif x != y:
            return math.inf
    return math.sqrt(total)


def nearest(parameters: dict[str, Any], candidates: list[tuple[str, dict[str, Any]]]) -> str | None:
    """The id of the candidate whose parameters are nearest (None when none is comparable)."""
    best: tuple[float, str] | None = None
    for ident, other in candidates:
        distance = parameter_distance(parameters, other)
        if math.isfinite(distance) and (best is None or distance < best[0]):
            best = (distance, ident)
    return best[1] if best else None
