"""The build hook that compiles the kept layouts' byte mover (`viewer_bridge/lcmcodec/_mover.c`).

hatchling runs it for wheels, editable installs included (`pip install -e .`, what `./dev` does):
the extension is compiled with the interpreter's own compiler settings (sysconfig's CC, include
directory and EXT_SUFFIX; `$CC` when set) next to its source, where an editable install imports it
from, and a wheel carries it (then tagged for this interpreter and platform). Without a working
compiler the build warns once and goes on: the package then moves bytes in Python, slower, the
same bytes (`viewer_bridge.lcmcodec.layout`). `python hatch_build.py` compiles it in place alone.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

SOURCE = Path("viewer_bridge") / "lcmcodec" / "_mover.c"


def extension_path(root: Path) -> Path:
    """Where the compiled mover goes: next to its source, named for this interpreter."""
    return root / SOURCE.with_name("_mover" + str(sysconfig.get_config_var("EXT_SUFFIX")))


def compile_mover(source: Path, target: Path) -> str | None:
    """Compiles the mover at `source` into `target`: None when done, else why not."""
    compiler = shlex.split(os.environ.get("CC") or str(sysconfig.get_config_var("CC") or "cc"))
    # Written beside the target, then renamed over it: a process that has the old module loaded
    # (a test run while a wheel is built from this tree) keeps its file, never a half-written one.
    written = target.with_name(f".{target.name}.{os.getpid()}")
    command = [*compiler, "-O2", "-fPIC", "-shared", "-I" + sysconfig.get_paths()["include"],
               str(source), "-o", str(written)]  # fmt: skip
    if sys.platform == "darwin":  # the interpreter provides Python's symbols when it loads the module
        command[-2:-2] = ["-undefined", "dynamic_lookup"]
    why = None
    try:
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            why = f"{shlex.join(command)} exited with {done.returncode}: {done.stderr.strip()}".strip(": ")
    except OSError as error:
        why = f"{shlex.join(command)}: {error}"
    if why is not None:
        written.unlink(missing_ok=True)
        target.unlink(missing_ok=True)  # no stale module from an earlier build
        return why
    os.replace(written, target)
    return None


class MoverBuildHook(BuildHookInterface):  # type: ignore[type-arg]
    PLUGIN_NAME = "custom"

    def initialize(self, version: str, build_data: dict[str, Any]) -> None:
        built = extension_path(Path(self.root))
        why = compile_mover(Path(self.root) / SOURCE, built)
        if why is not None:
            self.app.display_warning(
                f"viewer-bridge: the C byte mover was not compiled ({why}); the package works on its "
                "pure-Python movers, the same bytes, slower (viewer_bridge/lcmcodec/layout.py)"
            )
            return
        build_data["pure_python"] = False
        build_data["infer_tag"] = True  # cpXY-cpXY-platform: the module is built for this interpreter
        if version != "editable":  # an editable install imports it from the source tree, where it is
            build_data["force_include"][str(built)] = str(built.relative_to(self.root))


if __name__ == "__main__":
    ROOT = Path(__file__).resolve().parent
    reason = compile_mover(ROOT / SOURCE, extension_path(ROOT))
    print(f"not compiled: {reason}" if reason else extension_path(ROOT))
    sys.exit(reason is not None)
