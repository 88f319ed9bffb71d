"""A batch's children as pure logic: the grid's combinations in order, JSON pointers, Monte Carlo
draws (reproducible, with the asked spread), method lists, the request's validation, and the
summary rows read from result documents."""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from app.batch_plan import (
    PointerError,
    batch_size,
    expand,
    get_at,
    nearest,
    parameter_distance,
    set_at,
)
from app.report.batch import ROW_COLUMNS, render_summary_plot, summary_csv, summary_row
from app.schemas.batch import BatchRequest

BASE: dict[str, Any] = {
    "initial_state": {"velocity_m_s": 7450.0, "altitude_m": 100000.0},
    "vehicle": {"mass_kg": 104305.0},
    "no_fly_zones": [{"radius_deg": 2.0, "name": "a/b~c"}],
    "method": {"name": "foh-ptr", "nodes": 40},
}


def _request(**kind: Any) -> BatchRequest:
    return BatchRequest.model_validate({"base": {"scenario": "x"}, **kind})


def test_grid_children_cover_every_combination_first_parameter_slowest() -> None:
    request = _request(
        grid={
            "parameters": [
                {"path": "/no_fly_zones/0/radius_deg", "values": [1.0, 2.0, 3.0]},
                {"path": "/vehicle/mass_kg", "values": [9e4, 1e5]},
            ]
        }
    )
    children = expand(request, BASE)
    assert batch_size(request) == len(children) == 6
    combos = [
        (c.parameters["/no_fly_zones/0/radius_deg"], c.parameters["/vehicle/mass_kg"])
        for c in children
    ]
    assert combos == [(1.0, 9e4), (1.0, 1e5), (2.0, 9e4), (2.0, 1e5), (3.0, 9e4), (3.0, 1e5)]
    assert [c.index for c in children] == list(range(6))
    for child, (radius, mass) in zip(children, combos, strict=True):
        assert child.document["no_fly_zones"][0]["radius_deg"] == radius
        assert child.document["vehicle"]["mass_kg"] == mass
    assert BASE["no_fly_zones"][0]["radius_deg"] == 2.0  # the base is not touched


def test_pointers_follow_rfc_6901_and_name_where_they_fail() -> None:
    document = {"a/b": {"m~n": [10, 20]}}
    assert get_at(document, "/a~1b/m~0n/1") == 20
    set_at(document, "/a~1b/new", 5)
    assert document["a/b"]["new"] == 5
    with pytest.raises(PointerError, match="no member 'x'") as missing:
        set_at(document, "/x/y", 1)
    assert missing.value.pointer == "/x/y"
    with pytest.raises(PointerError, match="no item '2' in a list of 2"):
        set_at(document, "/a~1b/m~0n/2", 1)
    with pytest.raises(PointerError, match="not an object"):
        get_at(document, "/a~1b/new/deeper")


def test_monte_carlo_is_reproducible_and_has_the_asked_spread() -> None:
    spec = {
        "samples": 2000,
        "seed": 11,
        "dispersions": [
            {"path": "/initial_state/velocity_m_s", "distribution": "normal", "sigma": 20.0},
            {"path": "/vehicle/mass_kg", "distribution": "uniform", "half_width": 500.0},
        ],
    }
    first = expand(_request(monte_carlo=spec), BASE)
    again = expand(_request(monte_carlo=spec), BASE)
    assert [c.parameters for c in first] == [c.parameters for c in again]
    other = expand(_request(monte_carlo={**spec, "seed": 12}), BASE)
    assert [c.parameters for c in other] != [c.parameters for c in first]
    speed = np.array([c.parameters["/initial_state/velocity_m_s"] for c in first])
    mass = np.array([c.document["vehicle"]["mass_kg"] for c in first])
    # 2000 samples: the sample mean is within 4 standard errors (20/sqrt(2000) = 0.45 m/s)
    assert abs(speed.mean() - 7450.0) < 4 * 20.0 / np.sqrt(2000)
    assert 18.5 < speed.std() < 21.5  # the standard deviation within about 7 %
    assert mass.min() >= 104305.0 - 500.0 and mass.max() <= 104305.0 + 500.0
    assert mass.max() - mass.min() > 950.0  # the whole range is used


def test_a_dispersion_needs_a_number_at_its_path() -> None:
    spec = {
        "samples": 2,
        "dispersions": [{"path": "/method/name", "distribution": "normal", "sigma": 1}],
    }
    with pytest.raises(PointerError, match="needs a number"):
        expand(_request(monte_carlo=spec), BASE)


def test_methods_replace_the_whole_method() -> None:
    methods = [{"name": "foh-ptr", "grid": "uniform"}, {"name": "energy-scp"}]
    children = expand(_request(methods=methods), BASE)
    assert [c.document["method"] for c in children] == methods
    assert children[1].parameters == {"/method": {"name": "energy-scp"}}


def test_a_footprint_frees_the_final_latitude_and_seeks_each_edge_per_longitude() -> None:
    base = {**BASE, "terminal": {"longitude_deg": 12.0, "latitude_deg": 70.0}, "objective": "x"}
    request = _request(footprint={"longitudes_deg": [0.0, 12.0, 30.0]})
    children = expand(request, base)
    assert batch_size(request) == len(children) == 6
    assert [c.parameters for c in children[:2]] == [
        {"/terminal/longitude_deg": 0.0, "/objective": "max_final_latitude"},
        {"/terminal/longitude_deg": 0.0, "/objective": "min_final_latitude"},
    ]
    assert children[5].document["terminal"] == {
        "longitude_deg": 30.0,
        "latitude_deg": {"kind": "free"},
    }
    assert children[5].document["objective"] == "min_final_latitude"
    only_north = _request(
        footprint={"longitudes_deg": [0.0, 5.0], "extremes": ["max_final_latitude"]}
    )
    assert batch_size(only_north) == 2


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ({"grid": {"parameters": [{"path": "/a", "values": [1]}]}, "methods": [{}]}, "exactly one"),
        ({}, "exactly one"),
        ({"grid": {"parameters": [{"path": "a", "values": [1]}]}}, "pattern"),
        ({"grid": {"parameters": [{"path": "/a", "values": []}]}}, "at least 1"),
        (
            {
                "monte_carlo": {
                    "samples": 3,
                    "dispersions": [{"path": "/a", "distribution": "normal"}],
                }
            },
            "needs sigma",
        ),
        (
            {
                "monte_carlo": {
                    "samples": 3,
                    "dispersions": [{"path": "/a", "distribution": "uniform", "low": 2, "high": 1}],
                }
            },
            "below high",
        ),
    ],
)
def test_requests_are_validated(body: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        BatchRequest.model_validate({"base": {"scenario": "x"}, **body})


RESULT: dict[str, Any] = {
    "status": "succeeded",
    "objective": {"name": "max_terminal_velocity", "value": 936.4, "units": "m/s"},
    "verification": {
        "feasible": True,
        "final_state": {
            "altitude_m": 25000.1,
            "velocity_m_s": 936.5,
            "latitude_deg": 70.0,
            "longitude_deg": 12.0,
            "time_s": 1600.0,
        },
        "path_maxima": {"heat_rate_W_m2": {"max": 1.49e6, "limit": 1.5e6, "ratio": 0.9933}},
        "no_fly_zones": [{"min_clearance_deg": 0.0002}, {"min_clearance_deg": 3.0}],
    },
    "timing": {"wall_s": 0.45, "verification_s": 0.02, "iterations": 37},
}


def test_summary_rows_and_csv_read_the_results() -> None:
    rows = [
        summary_row(0, "j0", {"/no_fly_zones/0/radius_deg": 2.0}, "succeeded", None, RESULT),
        summary_row(1, "j1", {"/no_fly_zones/0/radius_deg": 9.0}, "failed", "infeasible", None),
    ]
    first = rows[0]
    assert first["objective"] == 936.4 and first["objective_units"] == "m/s"
    assert first["final_velocity_m_s"] == 936.5 and first["heat_rate_ratio"] == 0.9933
    assert first["load_factor_ratio"] is None  # no such limit in the result
    assert first["min_zone_clearance_deg"] == 0.0002
    assert first["iterations"] == 37 and first["optimization_s"] == 0.45
    assert rows[1]["failure_code"] == "infeasible" and rows[1]["objective"] is None
    table = list(csv.reader(io.StringIO(summary_csv(rows, ["/no_fly_zones/0/radius_deg"]))))
    assert table[0] == ["index", "job_id", "/no_fly_zones/0/radius_deg", *ROW_COLUMNS[2:]]
    assert float(table[1][table[0].index("objective")]) == 936.4
    assert table[2][table[0].index("objective")] == ""  # unknown: an empty cell
    for kind, paths in (
        ("grid", ["/no_fly_zones/0/radius_deg"]),
        ("monte_carlo", []),
        ("methods", []),
    ):
        png = render_summary_plot(kind, rows, paths, "png")
        assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_nearest_sibling_is_nearest_in_relative_terms_with_the_same_other_parameters() -> None:
    me = {"/r": 2.0, "/q": 1.5e6, "/objective": "max_final_latitude"}
    assert parameter_distance(me, me) == 0.0
    assert parameter_distance(me, {**me, "/objective": "min_final_latitude"}) == float("inf")
    # 2 -> 2.5 is a 20 % change, 1.5e6 -> 1.6e6 a 6.25 % one
    assert parameter_distance(me, {**me, "/r": 2.5}) == pytest.approx(0.2)
    candidates = [
        ("radius", {**me, "/r": 2.5}),
        ("heat", {**me, "/q": 1.6e6}),
        ("other edge", {**me, "/objective": "min_final_latitude"}),
    ]
    assert nearest(me, candidates) == "heat"
    assert nearest(me, candidates[2:]) is None  # nothing comparable: start cold
    assert nearest({"/method": {"name": "a"}}, [("b", {"/method": {"name": "b"}})]) is None
