# The compiled byte mover (`_mover.c`, built by hatch_build.py); `layout.py` builds its programs.

from collections.abc import Mapping

from viewer_bridge.lcmcodec.codegen import Buffer

def move(program: Buffer, data: Buffer, /) -> bytes | None: ...
def move_kept(programs: Mapping[int, object], data: bytes, /) -> bytes | None: ...
