"""Benchmark: draw -> foxglove.FrameTransforms bytes, beside the foxglove-sdk's own classes.

Run: .venv/bin/python bench/foxglove_live.py [--links 1000] [--budget 0.5]

Ours: `lcmt_viewer_draw` bytes -> `DrawDecoder` -> `FrameTransformsEncoder` (a per-name-set
protobuf wire template; numpy scatters the doubles and the stamp). Baseline: the SDK's way, a
`foxglove.messages.FrameTransform` built per link from the same decoded arrays, then
`FrameTransforms.encode()`. Both parse to the same `foxglove.FrameTransforms` (checked). Also the
once-per-load SceneUpdate of a 1000-geometry scene.

Then the live server: from `publish` of those bytes to a WebSocket client's receipt, a client
connected straight to the SDK's server over TLS (the baseline: what the SDK costs alone) beside
clients connected through our front (viewer_bridge/transports/foxglove_front.py) with either
subprotocol name, through a front that reaches the SDK in plain TCP (what the TLS between front
and SDK costs per frame: viewer_bridge/transports/sdk_tls.py), and through the front of a
read-only server (no client publishing: it reads along only the subscriptions, and the SDK's text
messages, to send again one the SDK refused too early).
Three figures each: one message at a time (publish, wait for it: the latency), a burst of
messages back to back (the time per message when the relay is kept busy), and the CPU per message
of that burst, of the whole process (SDK, front and client all run in it; steadier than the times
on a shared machine).
"""

from __future__ import annotations

import argparse
import json
import ssl
import time

from common import frame  # bench/ is on sys.path when run as a script
from draw_codec import seconds_per_call
from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms as FrameTransformsProto
from translators import scene
from websockets.sync.client import ClientConnection, connect

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.foxglove.scene import scene_update
from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.scene import LinkPoses
from viewer_bridge.transports.base import PROTOBUF, MessageType, Publisher, Qos
from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport


def sdk_frame_transforms(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> bytes:
    """The baseline: the SDK's FrameTransform objects, one per link, then its encoder."""
    timestamp = Timestamp(sec=stamp[0], nsec=stamp[1])
    transforms = [
        FrameTransform(
            timestamp=timestamp,
            parent_frame_id=frames.world_frame,
            child_frame_id=frames(name),
            translation=Vector3(x=position[0], y=position[1], z=position[2]),
            rotation=Quaternion(x=x, y=y, z=z, w=w),
        )
        for name, position, (w, x, y, z) in zip(
            poses.names, poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True
        )
    ]
    return bytes(FrameTransforms(transforms=transforms).encode())


def parsed(data: bytes) -> FrameTransformsProto:
    message = FrameTransformsProto()
    message.ParseFromString(data)
    return message


def subscribe(ws: ClientConnection) -> None:
    """Subscribes to the one channel the server advertises."""
    while (message := json.loads(ws.recv(timeout=10)))["op"] != "advertise":
        pass
    channel = message["channels"][0]["id"]
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]}))


def receive_data(ws: ClientConnection) -> int:
    """Waits for the next message-data frame; its size."""
    while True:
        frame = ws.recv(timeout=10)
        if isinstance(frame, bytes) and frame[0] == 0x01:
            return len(frame)


def wait_for_subscriber(publisher: Publisher) -> None:
    deadline = time.monotonic() + 10
    while publisher.subscriber_count() != 1:
        assert time.monotonic() < deadline, "the client's subscription never arrived"
        time.sleep(0.001)


def per_message(publisher: Publisher, ws: ClientConnection, payload: bytes, count: int, burst: bool) -> float:
    """Seconds per message from `publish` to its receipt, one at a time or `count` back to back."""
    start = time.perf_counter()
    if burst:
        for _ in range(count):
            publisher.publish(payload)
        for _ in range(count):
            receive_data(ws)
    else:
        for _ in range(count):
            publisher.publish(payload)
            receive_data(ws)
    return (time.perf_counter() - start) / count


def live_paths(payload: bytes, count: int, rounds: int = 5) -> dict[str, tuple[float, float, float]]:
    """(one at a time, in a burst) seconds per message for each way of reaching the server, the
    best of `rounds` alternating rounds (this machine's load drifts). The default server reads
    along what clients send (client publishing) and tracks where the SDK's messages end, and
    reaches the SDK over TLS (a certificate made per run, so that no web page can read the SDK's
    own port); beside it the same front reaching the SDK in plain TCP (`sdk_tls=False`: what the
    TLS costs per frame), and a read-only one (`client_publish: false`) that reads along only what
    repairs a refused subscription."""
    transport = FoxgloveTransport(FoxgloveSettings(port=0))
    plain = FoxgloveTransport(FoxgloveSettings(port=0), sdk_tls=False)
    read_only = FoxgloveTransport(FoxgloveSettings(port=0, client_publish=False))
    direct = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)  # a program of ours that knows the SDK's port
    direct.check_hostname, direct.verify_mode = False, ssl.CERT_NONE
    try:
        message_type = MessageType("foxglove.FrameTransforms", PROTOBUF)
        publisher = transport.publisher("/bench", message_type, Qos())
        on_plain = plain.publisher("/bench", message_type, Qos())
        relay_only = read_only.publisher("/bench", message_type, Qos())
        paths = {  # name: (publisher, url, subprotocol, TLS context)
            "SDK server alone (wss, baseline)": (
                publisher, f"wss://127.0.0.1:{transport.server.port}", "foxglove.sdk.v1", direct),
            "front, plain TCP to the SDK, .sdk.v1": (on_plain, f"ws://127.0.0.1:{plain.port}", "foxglove.sdk.v1", None),
            "front, TLS to the SDK, foxglove.sdk.v1": (publisher, f"ws://127.0.0.1:{transport.port}", "foxglove.sdk.v1",
                                                       None),
            "front, TLS to the SDK, .websocket.v1": (publisher, f"ws://127.0.0.1:{transport.port}",
                                                     "foxglove.websocket.v1", None),
            "read-only server's front, .websocket.v1": (relay_only, f"ws://127.0.0.1:{read_only.port}",
                                                        "foxglove.websocket.v1", None),
        }  # fmt: skip
        best: dict[str, tuple[float, float]] = {}
        for _ in range(rounds):
            for name, (on, url, subprotocol, context) in paths.items():
                with connect(url, subprotocols=[subprotocol], max_size=None, ssl=context) as ws:  # type: ignore[list-item]
                    assert ws.subprotocol == subprotocol
                    subscribe(ws)
                    wait_for_subscriber(on)
                    per_message(on, ws, payload, 20, burst=False)  # warm up
                    single = per_message(on, ws, payload, count, burst=False)
                    cpu = time.process_time()  # the SDK, the front and the client: all this process's
                    burst = per_message(on, ws, payload, count, burst=True)
                    cpu = (time.process_time() - cpu) / count
                old = best.get(name, (float("inf"),) * 3)
                best[name] = (min(old[0], single), min(old[1], burst), min(old[2], cpu))
        return best
    finally:
        transport.close()
        plain.close()
        read_only.close()


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, default=1000)
    parser.add_argument("--budget", type=float, default=0.5, help="seconds per measurement")
    parser.add_argument("--messages", type=int, default=500, help="messages per live measurement")
    args = parser.parse_args()

    draw = DrawEncoder().encode(frame(args.links))
    decoder, frames = DrawDecoder(), FrameNames()
    encoder = FrameTransformsEncoder(frames)
    stamp = (61, 250_000_000)

    def ours() -> bytes:
        return encoder.encode(decoder.decode(draw), stamp)

    def baseline() -> bytes:
        return sdk_frame_transforms(decoder.decode(draw), stamp, frames)

    assert parsed(ours()) == parsed(baseline())
    fast, slow = seconds_per_call(ours, args.budget), seconds_per_call(baseline, args.budget)
    print(f"draw -> foxglove.FrameTransforms bytes, {args.links} links (from lcmt_viewer_draw bytes)")
    print(f"  viewer-bridge wire template              {fast * 1e6:10.1f} us")
    print(f"  foxglove-sdk FrameTransform one by one   {slow * 1e6:10.1f} us")
    print(f"  ratio                                    {slow / fast:10.0f}x")

    load = scene(args.links)
    once = seconds_per_call(lambda: scene_update(load, frames).SerializeToString(), args.budget)
    print(
        f"\nload -> foxglove.SceneUpdate bytes, {load.geometry_count()} geometries: {once * 1e3:.2f} ms (once per load)"
    )

    for links in (10, args.links):  # a small message (mostly the hop's wake-ups) and a big one
        payload = encoder.encode(decoder.decode(DrawEncoder().encode(frame(links))), stamp)
        print(f"\nlive server, publish -> client receipt of a {len(payload)}-byte FrameTransforms, {links} links"
              " (best of 5 rounds)")  # fmt: skip
        print(f"  {'path':44} {'one at a time':>14} {'in a burst':>12} {'CPU, burst':>12}")
        for name, (single, burst, cpu) in live_paths(payload, args.messages).items():
            print(f"  {name:44} {single * 1e6:11.1f} us {burst * 1e6:9.1f} us {cpu * 1e6:9.1f} us")


if __name__ == "__main__":
    main()
