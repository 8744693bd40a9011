"""Output that is never a lie: every file the command line writes (an MCAP, a Rerun `.rrd`, an LCM
log, `.lcm` files, interface packages' sources) is written as `NAME.partial` and renamed to NAME
only once complete, so a file under its real name is always a whole result.

What is left when the writing stops midway is the same for every writer: a failure (an
exception) removes the `.partial`; a stop on purpose (`Interrupted`, raised by the writer when
Ctrl-C set its stop event, once it closed the file properly) keeps it, and the error says what it
holds, unless it holds no message yet: then it is removed, and the error says nothing is kept (an
empty file would look like a result). A live session's file (`run` into an MCAP or `.rrd`) ends
the same way when the session does (`finish`). A Ctrl-C that lands outside such a writer's loop (a
`KeyboardInterrupt`) counts as a failure: nothing is kept.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

from viewer_bridge.errors import Interrupted, UsageError

log = logging.getLogger("viewer_bridge")


def partial_path(target: Path) -> Path:
    """`NAME.partial` beside `target`; `target` itself when it is a `.partial` already (`convert`
    hands its file transports the `.partial` it renames, and keeps on Ctrl-C)."""
    return target if target.name.endswith(".partial") else target.with_name(target.name + ".partial")


@contextlib.contextmanager
def partial_output(target: str | Path) -> Iterator[Path]:
    """Yields the path to write (`target`'s `.partial`); renames it to `target` when the block ends
    normally (a writer that chose to write nothing leaves no `.partial` and gets no `target`).
    `Interrupted` keeps the `.partial`, unless it holds no message; any other exception removes it."""
    final = Path(target)
    partial = partial_path(final)
    try:
        yield partial
    except Interrupted as stopped:
        if not stopped.messages:  # its error says so: nothing kept
            _remove(partial)
        raise
    except BaseException:
        _remove(partial)
        raise
    if partial.exists() or partial.is_symlink():
        os.replace(partial, final)


def finish(partial: Path, final: Path, messages: int) -> None:
    """A live session's file, closed: `partial` renamed to `final` and said (`messages` in it), or
    removed when it holds no message, and said so."""
    if not messages:
        _remove(partial)
        log.warning("%s: no message was written: nothing kept", final)
        return
    os.replace(partial, final)
    log.info("wrote %s: %d messages", final, messages)


def write_whole(path: Path, text: str) -> None:
    """`text` into `path` (through its `.partial`): `path` holds the old text or the new, never a part."""
    with partial_output(path) as partial:
        partial.write_text(text)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def check_output_folder(folder: Path, option: str) -> None:
    """Refuse (`UsageError`, before any work) a folder to write into that cannot be one: it, or
    the nearest of its parents that exists, is not a folder."""
    existing = next((path for path in (folder, *folder.parents) if path.exists()), None)
    if existing is not None and not existing.is_dir():
        what = f"{existing} is a file" if existing == folder else f"{existing}, in its path, is a file"
        raise UsageError(f"{option} {folder}: {what}, not a folder: give a folder to write into")
