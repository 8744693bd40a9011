"""Fuzzing every decoder: only `DecodeError` may escape, memory stays bounded, nothing hangs."""

from __future__ import annotations

import resource
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.formats.drake.oracle import contact_results_to_lcm
from viewer_bridge.errors import DecodeError
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.examples.scenes import demo_contact_results
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.drake.load import decode_load, load_from_scene
from viewer_bridge.lcmcodec.codecs import (
    CODECS,
    CONTACT_RESULTS,
    DRAW,
    GEOMETRY_DATA,
    LINK_DATA,
    LOAD_ROBOT,
    VIEWER2_COMMS,
)

BUFFERS_PER_DECODER = 100_000
EXTREME_WORDS = [
    b"\x7f\xff\xff\xff",
    b"\x80\x00\x00\x00",
    b"\xff\xff\xff\xff",
    b"\x00\x00\x00\x00",
    b"\x00\x00\x00\x01",
    b"\x00\x00\x10\x00",
    b"\x7f\xc0\x00\x00",
]  # the last is NaN


def seeds(tmp_path: Path) -> dict[str, bytes]:
    scene = demo_scene()
    load = load_from_scene(scene)
    comms = VIEWER2_COMMS.message_class(
        utime=1, format="treeviewer_json", format_version_major=1, num_bytes=9, data=b'{"a": 1}\n'
    )
    contacts = contact_results_to_lcm(demo_contact_results(2, (2, 2), 1_500))
    surface = contacts.hydroelastic_contacts[0]
    quadrature = CODECS["drake.lcmt_hydroelastic_quadrature_per_point_data_for_viz"].message_class(
        p_WQ=[1.0, 2.0, 3.0], vt_BqAq_W=[0.0, 0.1, 0.0], traction_Aq_W=[0.0, 0.0, 5e4]
    )
    contacts_data = contacts.encode()
    # Drake sends no quadrature points today; the surface seed carries one so its decoder is reached.
    surface.num_quadrature_points, surface.quadrature_point_data = 1, [quadrature]
    return {
        "contacts": contacts_data,
        "point_pair": contacts.point_pair_contact_info[0].encode(),
        "surface": surface.encode(),
        "quadrature": quadrature.encode(),
        "point": surface.p_WV[0].encode(),
        "load": load.encode(),
        "link": load.link[1].encode(),
        "geometry": load.link[7].geom[0].encode(),  # a mesh array
        "draw": DrawEncoder().encode(demo_poses(scene, 1.0)),
        "comms": comms.encode(),
    }


def mutate(rng: np.random.Generator, seed: bytes) -> bytes:
    data = bytearray(seed)
    choice = rng.integers(0, 6)
    if choice == 0:  # flip a few bytes
        for position in rng.integers(0, len(data), rng.integers(1, 5)):
            data[position] = int(rng.integers(0, 256))
    elif choice == 1:  # truncate
        del data[int(rng.integers(0, len(data))) :]
    elif choice == 2:  # claim an extreme count or length somewhere
        position = int(rng.integers(8, max(len(data) - 4, 9)))
        data[position : position + 4] = EXTREME_WORDS[int(rng.integers(0, len(EXTREME_WORDS)))]
    elif choice == 3:  # append noise
        data += rng.bytes(int(rng.integers(1, 16)))
    elif choice == 4:  # random body behind the right fingerprint
        data = data[:8] + bytearray(rng.bytes(int(rng.integers(0, 200))))
    else:  # pure noise
        data = bytearray(rng.bytes(int(rng.integers(0, 64))))
    return bytes(data)


def fast_draw(data: bytes) -> Any:
    return DrawDecoder().decode(data)


DECODERS: list[tuple[str, str, Callable[[bytes], Any]]] = [
    ("load_robot", "load", LOAD_ROBOT.decode),
    ("load_robot -> scene", "load", decode_load),
    ("link_data", "link", LINK_DATA.decode),
    ("geometry_data", "geometry", GEOMETRY_DATA.decode),
    ("draw", "draw", DRAW.decode),
    ("draw (fast path)", "draw", fast_draw),
    ("viewer2_comms_t", "comms", VIEWER2_COMMS.decode),
    ("contact_results_for_viz", "contacts", CONTACT_RESULTS.decode),
    ("contact_results -> contacts", "contacts", decode_contact_results),
    ("point_pair_contact_info", "point_pair", CODECS["drake.lcmt_point_pair_contact_info_for_viz"].decode),
    (
        "hydroelastic_contact_surface",
        "surface",
        CODECS["drake.lcmt_hydroelastic_contact_surface_for_viz"].decode,
    ),
    (
        "hydroelastic_quadrature",
        "quadrature",
        CODECS["drake.lcmt_hydroelastic_quadrature_per_point_data_for_viz"].decode,
    ),
    ("point", "point", CODECS["drake.lcmt_point"].decode),
]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "seed_name", "decode"), DECODERS, ids=[d[0] for d in DECODERS])
def test_only_decode_errors_escape(
    name: str, seed_name: str, decode: Callable[[bytes], Any], tmp_path: Path
) -> None:
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    seed = seeds(tmp_path)[seed_name]
    decode(seed)  # the seed itself is valid
    before_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    outcomes = {"decoded": 0, "rejected": 0}
    for _ in range(BUFFERS_PER_DECODER):
        data = mutate(rng, seed)
        try:
            decode(data)
            outcomes["decoded"] += 1
        except DecodeError:
            outcomes["rejected"] += 1
    grown_mib = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before_kib) / 1024
    assert outcomes["rejected"] > BUFFERS_PER_DECODER // 2  # the mutations really were bad...
    assert outcomes["decoded"] > 0  # ...but not all of them: the fuzzer reaches valid inputs too
    assert grown_mib < 64, f"peak memory grew by {grown_mib:.0f} MiB"


def test_fast_draw_decoder_agrees_with_the_generic_one(tmp_path: Path) -> None:
    """On valid and mutated frames alike, the fast path and `DRAW.strict.decode` (what it falls back on) agree exactly."""
    rng = np.random.default_rng(7)
    seed = seeds(tmp_path)["draw"]
    decoder = DrawDecoder()
    for _ in range(5_000):
        data = mutate(rng, seed) if rng.random() < 0.7 else seed
        try:
            expected = DRAW.strict.decode(data)
        except DecodeError as error:
            with pytest.raises(DecodeError) as caught:
                decoder.decode(data)
            assert str(caught.value) == str(error)
            continue
        poses = decoder.decode(data)
        assert poses.names == tuple(expected.link_name)
        assert poses.positions.tolist() == expected.position
        assert poses.quaternions_wxyz.tolist() == expected.quaternion
        assert poses.robot_nums.tolist() == expected.robot_num
        assert poses.timestamp_ms == expected.timestamp


def test_huge_claimed_count_costs_no_memory() -> None:
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    claim = DRAW.packed_fingerprint + struct.pack(">qi", 0, 2**31 - 1) + b"\0" * 64
    for decode in (DRAW.decode, DRAW.strict.decode, fast_draw):
        with pytest.raises(DecodeError, match="count 2147483647"):
            decode(claim)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 16 * 1024
