"""The rerun transport: `.rrd` files read back with Rerun's own reader (`rerun.chunk.RrdReader`)
for a pydrake simulation's log converted by `viewer-bridge convert LOG OUT.rrd` and for draws
through the router (the SDK's chunks handed over as they are, no bytes between), and its bad
input: malformed draws and chunk bytes, a viewer that is not there, a file that cannot be
written, a port in use."""

from __future__ import annotations

import logging
import re
import signal
import socket
import subprocess
import sys
import time
from collections import Counter, defaultdict
from datetime import timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from tests.conftest import lcm_url
from viewer_bridge.cli.log_convert import convert
from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import ConvertError, DecodeError, TransportUnavailable
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.draw import DrawEncoder, poses_from_draw
from viewer_bridge.formats.drake.load import decode_load, load_from_scene
from viewer_bridge.formats.rerun.schema import Chunks, encode_batches
from viewer_bridge.lcmcodec.codecs import DRAW
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    LinkPoses,
    MeshFile,
    Sphere,
    TriangleMesh,
    frame_name,
)
from viewer_bridge.router.router import Router
from viewer_bridge.translators.types import RERUN_CHUNKS_TYPE
from viewer_bridge.transports.base import CallPublisher, Qos, Received, ValuePublisher, hand_over
from viewer_bridge.transports.lcm import LcmEvent
from viewer_bridge.transports.rerun import RerunSettings, RerunTransport


def rows_by_entity(path: Path) -> dict[str, list[dict[str, Any]]]:
    """Every row of the recording's chunks, by entity path (Rerun's reader, no code of ours)."""
    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in RrdReader(path).stream():
        table = chunk.to_record_batch().to_pylist()
        rows[chunk.entity_path].extend(table)
    return rows


@pytest.fixture(scope="module")
def drake_rrd(drake_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rerun") / "drake.rrd"
    written = convert(drake_log, out, load_config("builtin:rerun"), progress=False)
    assert written.written and not out.with_name("drake.rrd.partial").exists()
    # What `convert` says it wrote is what the file holds, less the SDK's own (/__properties).
    ours = [chunk.entity_path for chunk in RrdReader(out).stream() if not chunk.entity_path.startswith("/__")]
    assert written.chunks == dict(Counter(ours))
    assert written.summary() == f"wrote {out}: {len(ours)} chunks, {len(set(ours))} entities"
    return out


ROLES = {"ILLUSTRATION": "illustration", "PROXIMITY": "proximity"}


def test_every_link_and_geometry_is_an_entity_with_the_loads_sizes(
    drake_rrd: Path, drake_events: list[LcmEvent]
) -> None:
    rows = rows_by_entity(drake_rrd)
    checked = 0
    for role, root in ROLES.items():
        scene = decode_load(
            next(e.data for e in drake_events if e.channel == f"DRAKE_VIEWER_LOAD_ROBOT_{role}")
        )
        prefix = "" if root == "illustration" else "proximity/"
        for link in scene.links:
            if not link.geometries:
                continue
            path = (
                "/drake/"
                + root
                + "/"
                + "/".join(rr.escape_entity_path_part(p) for p in link.name.split("::"))
            )
            frame = "tf#/" if link.name == "world" else prefix + frame_name(link.name)
            assert rows[path][0]["CoordinateFrame:frame"] == [frame]
            for index, geometry in enumerate(link.geometries):
                (row,) = rows[f"{path}/{index}"]
                assert np.allclose(row["InstancePoses3D:translations"][0], geometry.pose.position, atol=1e-6)
                shape = geometry.shape
                if isinstance(shape, Box):
                    assert np.allclose(row["Boxes3D:half_sizes"][0], np.array(shape.size) / 2, rtol=1e-6)
                elif isinstance(shape, Sphere):
                    assert np.allclose(row["Ellipsoids3D:half_sizes"][0], [shape.radius] * 3, rtol=1e-6)
                elif isinstance(shape, Ellipsoid):
                    assert np.allclose(row["Ellipsoids3D:half_sizes"][0], shape.radii, rtol=1e-6)
                elif isinstance(shape, Cylinder | Capsule):
                    kind = "Cylinders3D" if isinstance(shape, Cylinder) else "Capsules3D"
                    assert np.isclose(row[f"{kind}:lengths"][0], shape.length, rtol=1e-6)
                    assert np.isclose(row[f"{kind}:radii"][0], shape.radius, rtol=1e-6)
                elif isinstance(shape, TriangleMesh):
                    assert len(row["Mesh3D:vertex_positions"]) == len(shape.vertices)
                    assert len(row["Mesh3D:triangle_indices"]) == len(shape.triangles)
                elif isinstance(shape, MeshFile):
                    assert bytes(row["Asset3D:blob"][0]) == Path(shape.path).read_bytes()
                else:
                    continue
                checked += 1
    assert checked >= 4


def test_transforms_equal_the_draws_at_their_sim_time(drake_rrd: Path, drake_events: list[LcmEvent]) -> None:
    rows = rows_by_entity(drake_rrd)
    for role, root in ROLES.items():
        by_time: dict[int, dict[str, Any]] = defaultdict(dict)
        for row in rows[f"/drake/{root}/transforms"]:
            by_time[row["sim_time"] // timedelta(milliseconds=1)][row["Transform3D:child_frame"][0]] = row
        channel = f"DRAKE_VIEWER_DRAW_{role}"
        draws = [poses_from_draw(DRAW.decode(e.data)) for e in drake_events if e.channel == channel]
        assert len(by_time) == len({draw.timestamp_ms for draw in draws}) > 1  # every draw recorded
        prefix = "" if root == "illustration" else "proximity/"
        for draw in draws:
            frames = by_time[draw.timestamp_ms]
            assert len(frames) == len(draw.names)
            for row_index, name in enumerate(draw.names):
                row = frames[prefix + frame_name(name)]
                assert row["Transform3D:parent_frame"] == ["tf#/"]
                assert np.allclose(row["Transform3D:translation"][0], draw.positions[row_index], atol=1e-6)
                w, x, y, z = draw.quaternions_wxyz[row_index]
                assert np.allclose(row["Transform3D:quaternion"][0], [x, y, z, w], atol=1e-6)


def test_convert_refuses_as_for_mcap(drake_log: Path, drake_rrd: Path, tmp_path: Path) -> None:
    with pytest.raises(ConvertError, match="exists"):
        convert(drake_log, drake_rrd, load_config("builtin:rerun"), progress=False)
    with pytest.raises(ConvertError, match="no route of the config reads LCM and writes Rerun chunks"):
        convert(drake_log, tmp_path / "out.rrd", load_config("builtin:foxglove"), progress=False)
    assert not list(tmp_path.iterdir())


def test_cli_convert_picks_rerun_by_extension(drake_log: Path, tmp_path: Path) -> None:
    out = tmp_path / "sim.rrd"
    done = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "convert", str(drake_log), str(out)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "/drake" in done.stdout and RrdReader(out).recordings()


def _transport(tmp_path: Path, **settings: Any) -> RerunTransport:
    return RerunTransport(RerunSettings(**settings))


def test_a_file_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(TransportUnavailable, match=r"rerun.path\): No such file or directory$"):
        _transport(tmp_path, path=tmp_path / "missing" / "out.rrd")
    (tmp_path / "out.rrd").write_bytes(b"")
    # What to type, on the command line where most runs start, and in a config.
    with pytest.raises(
        TransportUnavailable, match=r"exists \(rerun.path\): .* --set rerun.overwrite=true \("
    ):
        _transport(tmp_path, path=tmp_path / "out.rrd")
    with pytest.raises(TransportUnavailable, match="no sink"):
        _transport(tmp_path)


def test_a_port_in_use_is_one_line(tmp_path: Path) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(TransportUnavailable, match=rf"127.0.0.1:{port} \(rerun.grpc_port\): in use"):
            _transport(tmp_path, serve=True, grpc_port=port, web_port=0)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _draws_router(out: Path) -> Router:
    """A router with one drake_to_rerun route from LCM draws into the .rrd file `out`."""
    return Router(
        load_config("builtin:rerun").model_validate(
            {
                "lcm": {"url": "memq://"},
                "rerun": {"path": out},
                "routes": [
                    {
                        "name": "draws",
                        "source": {"transport": "lcm", "name": "DRAKE_VIEWER_DRAW"},
                        "translator": "drake_to_rerun",
                        "destination": {"transport": "rerun", "name": "/drake"},
                    }
                ],
            }
        )
    )


def _random_draw(rng: np.random.Generator, step: int, links: int) -> LinkPoses:
    quaternions = rng.normal(size=(links, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    names = tuple(f"plant::arm{link % 3}::link {link}" for link in range(links))  # a space: one path part
    return LinkPoses(step, names, np.zeros(links, np.int32), rng.normal(size=(links, 3)), quaternions)


def test_a_recording_of_no_message_keeps_no_file_and_says_so(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """As for MCAP: an `.rrd` of nothing but the SDK's own properties would look like a result."""
    out = tmp_path / "quiet.rrd"
    with caplog.at_level(logging.INFO, logger="viewer_bridge"):
        _draws_router(out).close()
    assert not list(tmp_path.iterdir())
    assert f"{out}: no message was written: nothing kept" in caplog.messages


def test_every_draw_through_the_router_is_in_the_rrd_with_its_values(tmp_path: Path) -> None:
    """Draws fed through the router (the SDK's chunks handed to the transport as they are), and
    malformed ones between them: each good draw's every link is in the file at its sim time, with
    its translation and rotation; each bad one is a counted DecodeError, and nothing else stops."""
    rng, encoder, out = np.random.default_rng(42), DrawEncoder(), tmp_path / "draws.rrd"
    router = _draws_router(out)
    draws = [_random_draw(rng, step + 1, links=40) for step in range(60)]
    for step, draw in enumerate(draws):
        data = encoder.encode(draw)
        router.feed("lcm", Received("DRAKE_VIEWER_DRAW", data))
        if step % 20 == 0:
            router.feed("lcm", Received("DRAKE_VIEWER_DRAW", data[: len(data) // 2]))  # cut short
            router.feed("lcm", Received("DRAKE_VIEWER_DRAW", b"\x00" * 16))  # no load, no draw
    stats = router.snapshot()["routes"]["draws"]
    router.close()
    assert stats["errors"] == {"DecodeError": 6} and stats["messages_out"] == len(draws)
    by_time: dict[int, dict[str, dict[str, Any]]] = defaultdict(dict)
    for row in rows_by_entity(out)["/drake/transforms"]:
        (child,) = row["Transform3D:child_frame"]
        by_time[row["sim_time"] // timedelta(milliseconds=1)][child] = row
    assert sorted(by_time) == [draw.timestamp_ms for draw in draws]  # every draw, once
    for draw in draws:
        frames = by_time[draw.timestamp_ms]
        assert sorted(frames) == sorted(frame_name(name) for name in draw.names)
        for index, name in enumerate(draw.names):
            row = frames[frame_name(name)]
            assert row["Transform3D:parent_frame"] == ["tf#/"]
            assert np.allclose(row["Transform3D:translation"][0], draw.positions[index], atol=1e-6)
            w, x, y, z = draw.quaternions_wxyz[index]
            assert np.allclose(row["Transform3D:quaternion"][0], [x, y, z, w], atol=1e-6)


def test_chunks_reach_a_publisher_that_takes_them_as_they_are_and_any_other_as_bytes() -> None:
    """The router's hand-over: the same object to a publisher of its type (no bytes made), its
    bytes to a publisher of bytes (a file, another process), which decode to the same rows."""
    from viewer_bridge.translators.registry import TRANSLATORS

    translator = TRANSLATORS["drake_to_rerun"]({})
    ((_, value),) = translator.translate(Received("DRAKE_VIEWER_DRAW", draw_of(small_scene(), 0.5)))
    assert isinstance(value, Chunks) and value.size > 0
    taken: list[Chunks] = []
    hand_over(ValuePublisher(Chunks, taken.append), value)
    assert taken == [value]
    sent: list[bytes] = []
    hand_over(CallPublisher(sent.append), value)
    (data,) = sent
    (chunk,), (decoded,) = value.chunks, Chunks.decode(data).chunks
    assert decoded.entity_path == chunk.entity_path == "/transforms"
    assert decoded.to_record_batch().to_pylist() == chunk.to_record_batch().to_pylist()


def test_chunk_bytes_that_are_no_chunks_are_a_decode_error(tmp_path: Path) -> None:
    """Where the chunks arrive as bytes (a publisher given bytes decodes them): a cut length, a
    cut stream, and a record batch with no Rerun metadata are each a DecodeError naming where."""
    import pyarrow as pa

    plain = encode_batches([pa.record_batch({"x": [1.0, 2.0]})])
    for data, where in ((b"\x01\x00", "length"), (plain[:-9], "stream"), (plain, "chunk")):
        with pytest.raises(DecodeError, match=where):
            Chunks.decode(data)
    transport = _transport(tmp_path, path=tmp_path / "bad.rrd")
    try:
        with pytest.raises(DecodeError):
            transport.publisher("/drake", RERUN_CHUNKS_TYPE, Qos()).publish(plain)
    finally:
        transport.close()


def test_a_viewer_that_is_not_there_stops_nothing(tmp_path: Path) -> None:
    """The gRPC sink to a closed port: the scene and every draw still reach the file beside it."""
    out = tmp_path / "out.rrd"
    router = Router(
        load_config("builtin:rerun")
        .model_copy(deep=True)
        .model_validate(
            {
                "lcm": {"url": "memq://"},
                "rerun": {"connect": f"rerun+http://127.0.0.1:{_free_port()}/proxy", "path": out},
                "routes": [
                    {
                        "name": "scene",
                        "source": {"transport": "lcm", "name": "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"},
                        "translator": "drake_to_rerun",
                        "destination": {"transport": "rerun", "name": "/drake"},
                    }
                ],
            }
        )
    )
    scene = small_scene()
    router.feed("lcm", Received("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode()))
    for step in range(20):
        router.feed("lcm", Received("DRAKE_VIEWER_DRAW", draw_of(scene, step)))
    router.close()
    rows = rows_by_entity(out)
    assert len({row["sim_time"] for row in rows["/drake/transforms"]}) == 20
    drawn = [link for link in scene.links if link.geometries]
    assert all("/drake/" + link.name.replace("::", "/") in rows for link in drawn)


def test_the_served_data_names_only_loopback_and_rerun_pages_for_cors(tmp_path: Path) -> None:
    """What docs/rerun.md says of the gRPC server `rerun.serve` starts: it answers every origin
    (no check of its own the bridge could set), and a browser lets a page call it only when the
    answer names the page's origin in Access-Control-Allow-Origin: localhost, 127.0.0.1 and
    rerun.io, not another page (nor [::1])."""
    import http.client

    transport = _transport(tmp_path, serve=True, grpc_port=0, web_port=0)
    try:

        def preflight(origin: str) -> tuple[int, str | None]:
            connection = http.client.HTTPConnection("127.0.0.1", transport.grpc_port, timeout=30)
            try:
                connection.request("OPTIONS", "/rerun.sdk_comms.v1alpha1.MessageProxyService/ReadMessages",
                                   headers={"Origin": origin, "Access-Control-Request-Method": "POST",
                                            "Access-Control-Request-Headers": "content-type,x-grpc-web"})  # fmt: skip
                response = connection.getresponse()
                return response.status, response.getheader("Access-Control-Allow-Origin")
            finally:
                connection.close()

        for origin in ("http://localhost:3000", "http://127.0.0.1:9090", "https://rerun.io"):
            assert preflight(origin) == (200, origin)
        for origin in ("https://evil.example", "http://[::1]:9090"):
            assert preflight(origin) == (200, None)  # answered, but a browser keeps the page out
    finally:
        transport.close()


def _bridge_to_viewer(port: int, *more: str) -> subprocess.Popen[str]:
    """`run -c builtin:rerun --demo` to a viewer's URL on `port`, its stderr a pipe (as under a
    script, where colour codes would be noise)."""
    return subprocess.Popen(
        [sys.executable, "-m", "viewer_bridge", "run", "-c", "builtin:rerun", "--demo", "--lcm-url", lcm_url(49),
         "--stats-period", "1", "--set", f"rerun.connect=rerun+http://127.0.0.1:{port}/proxy", *more],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _lines_until(stream: Any, text: str, lines: list[str]) -> None:
    for line in stream:
        lines.append(line)
        if text in line:
            return
    raise AssertionError("".join(lines))


def test_no_viewer_is_said_at_start_counted_as_unsent_and_does_not_hold_up_the_stop() -> None:
    bridge = _bridge_to_viewer(_free_port(), "--duration", "120")
    lines: list[str] = []
    try:
        assert bridge.stderr is not None
        _lines_until(bridge.stderr, "rerun: no viewer answers at rerun+http://127.0.0.1:", lines)
        assert "start one with `rerun`" in lines[-1]
        _lines_until(bridge.stderr, "transport errors: rerun: ", lines)  # a stats period with draws
        assert re.search(r"route rerun_scene: in \d+ out (\d+) errors 0 unsent [1-9]", "".join(lines)), lines
        assert re.search(r"transport errors: rerun: \d+ unsent no viewer$", lines[-1]), lines[-1]
        bridge.send_signal(signal.SIGINT)
        asked = time.monotonic()
        rest = bridge.communicate(timeout=60)[1]
        stopped = time.monotonic() - asked
    finally:
        bridge.kill()
    said = "".join(lines) + rest
    assert bridge.returncode == 0, said
    # The SDK's client, left unconnected, would wait 5 s for a viewer (and say so in Rust's log).
    assert stopped < 4, (stopped, said)
    assert "\x1b[" not in said and "re_grpc_client" not in said and "Traceback" not in said, said


def test_a_viewer_started_later_gets_what_was_kept_for_it(tmp_path: Path) -> None:
    """`rerun --save FILE` is a viewer's gRPC server that writes what it receives: started after the
    bridge, it gets the scene logged before it came, and the draws."""
    port = _free_port()
    bridge = _bridge_to_viewer(port, "--duration", "120")
    received = tmp_path / "received.rrd"
    lines: list[str] = []
    viewer = None
    try:
        assert bridge.stderr is not None
        _lines_until(bridge.stderr, "transport errors: rerun: ", lines)  # logged, and kept
        viewer = subprocess.Popen([str(Path(sys.executable).parent / "rerun"), "--port", str(port), "--save",
                                   str(received)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
        _lines_until(bridge.stderr, "rerun: a viewer answered at ", lines)
        _lines_until(bridge.stderr, "route rerun_scene: ", lines)  # a period later
        bridge.send_signal(signal.SIGINT)
        bridge.communicate(timeout=60)
    finally:
        bridge.kill()
        if viewer is not None:
            viewer.terminate()
            viewer.wait(timeout=60)
    rows = rows_by_entity(received)
    assert any(path.startswith("/drake/") and path != "/drake/transforms" for path in rows), sorted(rows)[:10]
    assert len(rows["/drake/transforms"]) > 1
