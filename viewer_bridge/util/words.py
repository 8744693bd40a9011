"""Counts said in words, the one way every message of the bridge says them."""

from __future__ import annotations


def counted(count: int, noun: str, plural: str | None = None) -> str:
    """`1 route`, `2 routes`: a count and its noun, singular or plural (`noun` + s unless given)."""
    return f"{count} {noun}" if count == 1 else f"{count} {plural or noun + 's'}"
