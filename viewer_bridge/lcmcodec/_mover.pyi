# The compiled byte mover (`_mover.c`, built by hatch_build.py); `layout.py` builds its programs.

from viewer_bridge.lcmcodec.codegen import Buffer

def move(program: Buffer, data: Buffer, /) -> bytes | None: ...
