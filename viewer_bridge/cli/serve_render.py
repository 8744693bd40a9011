"""`viewer-bridge serve-render`: Drake's glTF render API (RenderEngineGltfClient), served over HTTP."""

from __future__ import annotations

import argparse
import logging
import signal
import threading

from viewer_bridge.cli.arguments import AddCommand, byte_count, port
from viewer_bridge.errors import UsageError
from viewer_bridge.transports.origins import ANY_ORIGIN, is_origin_pattern


def add_command(add: AddCommand) -> None:
    """The `serve-render` command's arguments, on the parser `add` makes."""
    serve = add("serve-render", help="serve Drake's glTF render API (RenderEngineGltfClient)")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1: this host only)")
    serve.add_argument("--port", type=port, default=8000, help="TCP port to listen on (0: any free port)")
    serve.add_argument(
        "--max-upload",
        type=byte_count,
        default=256 * 1024 * 1024,
        metavar="BYTES",
        help="largest request body accepted, and the most the requests being read hold together (others wait)",
    )
    serve.add_argument(
        "--max-requests",
        type=_request_count,
        default=8,
        metavar="N",
        help="requests at once, being read, rendered or waiting; more are answered 503 with Retry-After",
    )
    serve.add_argument(
        "--max-image",
        type=_image_size,
        default="4096x4096",
        metavar="WIDTHxHEIGHT",
        help="largest image rendered; a larger one is refused (400) naming this limit",
    )
    serve.add_argument(
        "--allow-origin",
        action="append",
        type=_origin,
        default=[],
        metavar="ORIGIN",
        help="also accept posts from browser pages of this origin (scheme://host[:port], * for any run of "
        "characters but /; '*': any page); loopback pages and clients that send no Origin always may; repeatable",
    )


def _request_count(text: str) -> int:
    """A --max-requests value: 1 to 1024."""
    if not text.isdigit() or not 1 <= int(text) <= 1024:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of requests from 1 to 1024")
    return int(text)


def _image_size(text: str) -> tuple[int, int]:
    """A --max-image value: WIDTHxHEIGHT, each 1 to 16384 (`4096x4096`)."""
    width, separator, height = text.lower().partition("x")
    if not (
        separator
        and width.isdigit()
        and height.isdigit()
        and 0 < int(width) <= 16384
        and 0 < int(height) <= 16384
    ):
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT, each 1 to 16384 (e.g. 4096x4096)")
    return int(width), int(height)


def _origin(text: str) -> str:
    """An --allow-origin value: an origin or a pattern of origins (no path: browsers send none)."""
    if not is_origin_pattern(text):
        raise argparse.ArgumentTypeError(f"{text!r} is no origin: write scheme://host[:port] (no path), "
                                         "with * for any run of characters but '/', or '*' alone")  # fmt: skip
    return text


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C or SIGTERM; a host or port that cannot be listened on is one line."""
    from viewer_bridge.render.server import make_server  # OpenGL only for this command

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
    try:
        server = make_server(
            args.host, args.port, args.max_upload, args.allow_origin, args.max_requests, args.max_image
        )
    except OSError as error:  # e.g. the port is taken, or the host is not an address of this machine
        raise UsageError(f"cannot listen on {args.host}:{args.port}: {error.strerror or error}") from None
    # Ctrl-C stops it cleanly from the moment it says it is ready.
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: threading.Thread(target=server.shutdown).start())
    # Drake's client takes the base URL and adds the endpoint (/render) itself: print that one.
    host, port_number = server.server_address[:2]
    host = host.decode() if isinstance(host, bytes) else host
    base_url = f"http://{host}:{port_number}"
    logging.getLogger("viewer_bridge").info(
        'render server on %s (Drake: RenderEngineGltfClientParams(base_url="%s"), which posts to /render)%s',
        base_url,
        base_url,
        "; origin check off: any web page may post" if ANY_ORIGIN in args.allow_origin else "",
    )
    server.serve_forever()
    server.server_close()
    return 0
