"""Any LCM message's numbers as Rerun `Scalars`: one entity per field path, so each plots alone.

A message (as `LcmType.to_dict` gives it) is walked field by field: a number or a boolean is one
scalar at its path (`joint_position_measured` with 7 values is one entity with 7 series), a
nested message adds its field names to the path, an array of messages their indices
(`plan/3/utime`). Strings and byte arrays are no numbers and are left out.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import rerun as rr

FieldPath = tuple[str, ...]

# Drake's and most labs' LCM types say when a message was made in this field (microseconds).
TIME_FIELDS = ("utime",)


def numeric_fields(
    message: Mapping[str, Any], path: FieldPath = ()
) -> Iterator[tuple[FieldPath, list[float]]]:
    """(field path, its numbers) for every numeric field of a JSON-ready message, in field order."""
    for name, value in message.items():
        yield from _numbers(value, (*path, name))


def _numbers(value: Any, path: FieldPath) -> Iterator[tuple[FieldPath, list[float]]]:
    if isinstance(value, bool | int | float):
        yield path, [float(value)]
    elif isinstance(value, Mapping):
        if "bytes" in value and "crc32" in value:  # a byte array's summary: no numbers to plot
            return
        yield from numeric_fields(value, path)
    elif isinstance(value, Sequence) and not isinstance(value, str):
        flat = _flat_numbers(value)
        if flat is not None:
            if flat:
                yield path, flat
            return
        for index, item in enumerate(value):
            yield from _numbers(item, (*path, str(index)))


def _flat_numbers(value: Sequence[Any]) -> list[float] | None:
    """The numbers of an array of numbers (of any number of dimensions, row-major), or None when
    it holds anything else (messages, strings)."""
    flat: list[float] = []
    stack = [iter(value)]
    while stack:
        item = next(stack[-1], _END)
        if item is _END:
            stack.pop()
        elif isinstance(item, bool | int | float):
            flat.append(float(item))
        elif isinstance(item, list | tuple):
            stack.append(iter(item))
        else:
            return None
    return flat


_END = object()


def scalars_of(message: Mapping[str, Any]) -> list[tuple[FieldPath, rr.Scalars]]:
    """A `Scalars` per numeric field of a JSON-ready message."""
    return [(path, rr.Scalars(values)) for path, values in numeric_fields(message)]


def sim_time_us(message: Mapping[str, Any]) -> int | None:
    """When the message says it was made (its `utime`, in microseconds, LCM's convention), or None."""
    for name in TIME_FIELDS:
        value = message.get(name)
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    return None
