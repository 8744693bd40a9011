"""formats/rerun/scalars: the numbers of any LCM message, by field path."""

from __future__ import annotations

from viewer_bridge.formats.rerun.scalars import numeric_fields, sim_time_us


def test_every_number_by_its_field_path_and_nothing_else() -> None:
    message = {
        "utime": 7,
        "ok": True,
        "name": "arm",  # a string: no number
        "image": {"bytes": 12, "crc32": "0badf00d"},  # a byte array's summary: no number
        "q": [0.5, -1.0],
        "grid": [[1, 2, 3], [4, 5, 6]],  # two dimensions, row-major
        "empty": [],
        "pose": {"x": 1.5, "frame": "world"},
        "plan": [{"utime": 1, "names": ["a"], "q": [0.1]}, {"utime": 2, "names": ["b"], "q": [0.2]}],
    }
    assert list(numeric_fields(message)) == [
        (("utime",), [7.0]),
        (("ok",), [1.0]),
        (("q",), [0.5, -1.0]),
        (("grid",), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
        (("pose", "x"), [1.5]),
        (("plan", "0", "utime"), [1.0]),
        (("plan", "0", "q"), [0.1]),
        (("plan", "1", "utime"), [2.0]),
        (("plan", "1", "q"), [0.2]),
    ]


def test_the_sim_time_is_a_messages_utime() -> None:
    assert sim_time_us({"utime": 1500, "x": 1}) == 1500
    assert sim_time_us({"timestamp": 1500}) is None and sim_time_us({"utime": True}) is None
