"""JSON Merge Patch (RFC 7396) and the variant rule of overrides, on plain data and small models."""

from __future__ import annotations

import copy
from typing import Annotated, Any, Literal

import pytest
from pydantic import BaseModel, BeforeValidator, Field

from app.submission import TaggedUnion, merge_patch, problem_unions, tagged_unions

# RFC 7396, Appendix A ("Example Test Cases"): original, patch, result.
RFC_7396_APPENDIX_A: list[tuple[Any, Any, Any]] = [
    ({"a": "b"}, {"a": "c"}, {"a": "c"}),
    ({"a": "b"}, {"b": "c"}, {"a": "b", "b": "c"}),
    ({"a": "b"}, {"a": None}, {}),
    ({"a": "b", "b": "c"}, {"a": None}, {"b": "c"}),
    ({"a": ["b"]}, {"a": "c"}, {"a": "c"}),
    ({"a": "c"}, {"a": ["b"]}, {"a": ["b"]}),
    ({"a": {"b": "c"}}, {"a": {"b": "d", "c": None}}, {"a": {"b": "d"}}),
    ({"a": [{"b": "c"}]}, {"a": [1]}, {"a": [1]}),
    (["a", "b"], ["c", "d"], ["c", "d"]),
    ({"a": "b"}, ["c"], ["c"]),
    ({"a": "foo"}, None, None),
    ({"a": "foo"}, "bar", "bar"),
    ({"e": None}, {"a": 1}, {"e": None, "a": 1}),
    ([1, 2], {"a": "b", "c": None}, {"a": "b"}),
    ({}, {"a": {"bb": {"ccc": None}}}, {"a": {"bb": {}}}),
]

# RFC 7396, Section 3: the worked example.
RFC_7396_SECTION_3: tuple[dict[str, Any], dict[str, Any], dict[str, Any]] = (
    {
        "title": "Goodbye!",
        "author": {"givenName": "John", "familyName": "Doe"},
        "tags": ["example", "sample"],
        "content": "This will be unchanged",
    },
    {
        "title": "Hello!",
        "phoneNumber": "+01-123-456-7890",
        "author": {"familyName": None},
        "tags": ["example"],
    },
    {
        "title": "Hello!",
        "author": {"givenName": "John"},
        "tags": ["example"],
        "content": "This will be unchanged",
        "phoneNumber": "+01-123-456-7890",
    },
)


@pytest.mark.parametrize(("original", "patch", "expected"), RFC_7396_APPENDIX_A)
def test_rfc_7396_appendix_a(original: Any, patch: Any, expected: Any) -> None:
    """Every published example case gives the published result."""
    assert merge_patch(original, patch) == expected


def test_rfc_7396_section_3_example_and_inputs_left_alone() -> None:
    """The worked example of the RFC; neither the target nor the patch is modified."""
    original, patch, expected = copy.deepcopy(RFC_7396_SECTION_3)
    result = merge_patch(original, patch)
    assert result == expected
    assert (original, patch) == RFC_7396_SECTION_3[:2]
    result["author"]["givenName"] = "Jane"
    result["tags"].append("x")
    assert original["author"]["givenName"] == "John"
    assert patch["tags"] == ["example"]


class Cat(BaseModel):
    """A variant tagged ``kind: cat``."""

    kind: Literal["cat"] = "cat"
    lives: int = 9
    indoor: bool = True


class Dog(BaseModel):
    """A variant tagged ``kind: dog``."""

    kind: Literal["dog"] = "dog"
    breed: str = "mixed"


def _cat_by_default(value: Any) -> Any:
    """An object without ``kind`` is a cat (like a method without ``name``)."""
    if isinstance(value, dict) and "kind" not in value:
        return {**value, "kind": "cat"}
    return value


Pet = Annotated[Cat | Dog, Field(discriminator="kind")]


class Owner(BaseModel):
    """Unions at every kind of place: a field, an optional field, list items, mapping values."""

    pet: Annotated[Pet, BeforeValidator(_cat_by_default)]
    spare: Pet | None = None
    pets: list[Pet] = []
    by_name: dict[str, Pet] = {}
    note: str = ""


@pytest.fixture(scope="module")
def unions() -> tuple[TaggedUnion, ...]:
    return tagged_unions(Owner)


def test_unions_are_found_from_the_model(unions: tuple[TaggedUnion, ...]) -> None:
    """Every discriminated union is found with its key and tags, wherever it sits."""
    found = {(u.location, u.key, u.tags) for u in unions}
    assert found == {
        (place, "kind", ("cat", "dog")) for place in ("pet", "spare", "pets[]", "by_name.*")
    }


def test_changing_the_tag_replaces_the_object(unions: tuple[TaggedUnion, ...]) -> None:
    """The new variant holds only the patch's members, its nulls dropped as in RFC 7396."""
    base = {"pet": {"kind": "cat", "lives": 3}, "note": "n"}
    result = merge_patch(base, {"pet": {"kind": "dog", "lives": None}}, unions)
    assert result == {"pet": {"kind": "dog"}, "note": "n"}
    assert Owner.model_validate(result).pet == Dog()
    result = merge_patch(base, {"spare": {"kind": "dog"}, "pet": {"kind": "dog"}}, unions)
    assert result["spare"] == {"kind": "dog"}
    by_name = {"by_name": {"rex": {"kind": "cat", "lives": 1}}}
    assert merge_patch(by_name, {"by_name": {"rex": {"kind": "dog", "breed": "pug"}}}, unions) == {
        "by_name": {"rex": {"kind": "dog", "breed": "pug"}}
    }


def test_same_tag_or_no_tag_merges(unions: tuple[TaggedUnion, ...]) -> None:
    """The same variant, or a patch without the tag, merges member by member."""
    base = {"pet": {"kind": "cat", "lives": 3, "indoor": False}}
    assert merge_patch(base, {"pet": {"kind": "cat", "lives": 4}}, unions) == {
        "pet": {"kind": "cat", "lives": 4, "indoor": False}
    }
    assert merge_patch(base, {"pet": {"indoor": None}}, unions) == {
        "pet": {"kind": "cat", "lives": 3}
    }


def test_a_missing_tag_counts_as_the_variant_validation_picks(
    unions: tuple[TaggedUnion, ...],
) -> None:
    """An untagged object that validation makes a cat is a cat; one it cannot place merges."""
    base = {"pet": {"lives": 3}}
    assert merge_patch(base, {"pet": {"kind": "cat", "indoor": False}}, unions) == {
        "pet": {"lives": 3, "kind": "cat", "indoor": False}
    }
    assert merge_patch(base, {"pet": {"kind": "dog"}}, unions) == {"pet": {"kind": "dog"}}
    untagged = {"spare": {"breed": "pug"}}  # no default variant: the patch completes it
    assert merge_patch(untagged, {"spare": {"kind": "dog"}}, unions) == {
        "spare": {"breed": "pug", "kind": "dog"}
    }


def test_the_rule_applies_only_where_a_union_sits(unions: tuple[TaggedUnion, ...]) -> None:
    """A ``kind`` member elsewhere, and objects inside replaced arrays, are plain data."""
    base = {"note": {"kind": "cat", "lives": 1}, "pets": [{"kind": "cat", "lives": 2}]}
    result = merge_patch(base, {"note": {"kind": "dog"}, "pets": [{"kind": "dog"}]}, unions)
    assert result == {"note": {"kind": "dog", "lives": 1}, "pets": [{"kind": "dog"}]}


def test_problem_document_unions() -> None:
    """The problem contract's unions: the list docs/problem-contract.md gives."""
    found = {u.location: u.key for u in problem_unions()}
    terminal = [
        *("altitude_m", "longitude_deg", "latitude_deg", "velocity_m_s"),
        *("flight_path_angle_deg", "heading_deg"),
    ]
    assert found == {
        "vehicle.aerodynamics": "model",
        "vehicle.angle_of_attack": "mode",
        "planet.atmosphere": "model",
        **{f"terminal.{name}": "kind" for name in terminal},
        "final_time": "kind",
        **{f"phases[].end.{name}": "kind" for name in terminal},
        "method": "name",
    }
    atmosphere = next(u for u in problem_unions() if u.location == "planet.atmosphere")
    assert atmosphere.tags == ("exponential", "us76")
