"""The kept-layout check every direction shares (`viewer_bridge.lcmcodec.layout`): a converter that
keeps layouts and the generated code alone give the same bytes, or the same error, for a message
of a kept layout's size with its bytes changed anywhere."""

from __future__ import annotations

from collections.abc import Callable

from hypothesis import given, settings
from hypothesis import strategies as st

from viewer_bridge.errors import DecodeError

Convert = Callable[[bytes], bytes]


def outcome(convert: Convert, data: bytes) -> bytes | str:
    """What `convert` makes of `data`: its bytes, or its error's text."""
    try:
        return convert(data)
    except DecodeError as error:
        return str(error)


def assert_damage_agrees(
    kept: Convert, generated: Convert, data: bytes, *, changes: int, examples: int
) -> None:
    """`data` with up to `changes` bytes set to anything (lengths, counts, NULs, UTF-8, bools,
    numbers) converts or fails through `kept` as through `generated`, byte for byte."""

    @given(st.lists(st.tuples(st.integers(0, len(data) - 1), st.integers(0, 255)), max_size=changes))
    @settings(max_examples=examples, deadline=None)
    def check(damage: list[tuple[int, int]]) -> None:
        changed = bytearray(data)
        for index, value in damage:
            changed[index] = value
        assert outcome(kept, bytes(changed)) == outcome(generated, bytes(changed))

    check()
