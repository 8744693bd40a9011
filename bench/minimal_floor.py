"""The floor written from scratch: the least a Python process can do to move LCM messages onto Zenoh.

Run by bench/floor.py (`--serve`-style: pinned by its parent), never on its own. Arguments: the
LCM URL and a Zenoh router's endpoint. `lc.handle()` in the main thread, one Zenoh publisher per
channel (key lcm/<channel>), the bytes put as they are; nothing else on the message's path. A line
on stdin asks for {"count": messages received, "cpu": this process's CPU seconds} on stdout; the
end of stdin ends the process. Written apart from bench/floor.py's floors on purpose: the bench's
floor row and this agree (within 20%) or the bench measures something else than the floor.
"""

import json
import os
import sys
import threading
import time
from collections.abc import Callable

import lcm
import zenoh

url, endpoint = sys.argv[1], sys.argv[2]
config = zenoh.Config()
config.insert_json5("mode", '"client"')
config.insert_json5("connect/endpoints", json.dumps([endpoint]))
config.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(config)
puts: dict[str, Callable[[bytes], None]] = {}
count = 0


def on_message(channel: str, data: bytes) -> None:
    global count
    put = puts.get(channel)
    if put is None:
        put = puts[channel] = session.declare_publisher(f"lcm/{channel}").put
    put(data)
    count += 1


def answer() -> None:
    for _ in sys.stdin:  # blocked in read: costs the loop nothing
        print(json.dumps({"count": count, "cpu": time.process_time()}), flush=True)
    os._exit(0)


lc = lcm.LCM(url)
lc.subscribe(".*", on_message)
threading.Thread(target=answer, daemon=True).start()
print("ready", flush=True)
while True:
    lc.handle()
