"""Builders for the small scores (their JSON form) the tests write by hand: the envelope, a
``sync`` block, a ``cstr`` block, and a hand shape held while a contact is made."""

from __future__ import annotations


def envelope(root: dict, strong_side: str = "R") -> dict:
    """A version 1 score around ``root``."""
    return {"format": "azee-score", "version": 1, "strong_side": strong_side, "root": root}


def sync(name: str, end: float, *children: dict, start: float = 0) -> dict:
    """A ``sync`` block from ``start`` to ``end`` (seconds) with ``children``."""
    return {"name": name, "kind": "sync", "start": start, "end": end, "children": list(children)}


def cstr(name: str, start: float, end: float, *constraints: dict) -> dict:
    """A ``cstr`` block from ``start`` to ``end`` (seconds) with ``constraints``."""
    return {
        "name": name,
        "kind": "cstr",
        "start": start,
        "end": end,
        "constraints": list(constraints),
    }


def shaped(
    shape: list[dict],
    start: float,
    end: float,
    *constraints: dict,
    names: tuple[str, str, str] = ("C", "HS", "K"),
) -> dict:
    """A score whose hand ``shape`` holds from 0 to ``end`` (seconds) while ``constraints``
    hold from ``start``: a ``sync`` root with the shape's block and the constraints' block,
    named ``names`` (root, shape, constraints)."""
    root, hs, k = names
    return envelope(sync(root, end, cstr(hs, 0, end, *shape), cstr(k, start, end, *constraints)))
