"""The compiled byte mover (`viewer_bridge/lcmcodec/_mover.c`) and the programs `layout` builds for
it: built and used here, held byte for byte to the generated code on Drake's iiwa messages both
ways (sizes that change, truncation, a count claiming 2^31, every shape value altered), and held
to a Python reading of the same program on random programs and inputs."""

from __future__ import annotations

import importlib
import importlib.util
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import drake
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hatch_build
from tests.lcmcodec.kept import outcome
from viewer_bridge.lcmcodec import layout
from viewer_bridge.lcmcodec.layout import MoveProgram
from viewer_bridge.lcmcodec.library import TypeLibrary

ROOT = Path(__file__).resolve().parents[2]
_HEADER, _CHECK, _RUN = 4, 5, 7  # words: `_mover.c`'s records
_EQUAL, _AT_MOST, _UTF8 = 0, 1, 2
_SWAP, _NONZERO = 1, 2


# --- a Python reading of a program: what the C code must do --------------------------------------------


def _fits(at: int, count: int, step: int, width: int, size: int) -> bool:
    return count == 0 or at + (count - 1) * step + width <= size


def _parse(program: bytes) -> tuple[int, int, list[tuple[int, ...]], list[tuple[int, ...]], bytes, bytes]:
    """(input size, output size, checks, runs, template, blob), or ValueError when malformed."""
    if len(program) < 4 * _HEADER:
        raise ValueError("no header")
    input_size, output_size, n_checks, n_runs = struct.unpack_from("=4I", program)
    records = 4 * (_HEADER + _CHECK * n_checks + _RUN * n_runs)
    if records + output_size > len(program):
        raise ValueError("short")
    words = struct.unpack_from(f"={records // 4}I", program)[_HEADER:]
    checks = [words[_CHECK * i : _CHECK * (i + 1)] for i in range(n_checks)]
    runs = [words[_CHECK * n_checks + _RUN * i :][:_RUN] for i in range(n_runs)]
    template, blob = program[records : records + output_size], program[records + output_size :]
    for kind, at, count, step, arg in checks:
        if kind not in (_EQUAL, _AT_MOST, _UTF8):
            raise ValueError("kind")
        within = _fits(at, count, step if kind == _AT_MOST else 1, 1, input_size)
        if (
            not within
            or (kind == _EQUAL and not _fits(arg, count, 1, 1, len(blob)))
            or (kind == _AT_MOST and arg > 255)
        ):
            raise ValueError("check")
    for in_at, out_at, count, in_step, out_step, width, flags in runs:
        if (
            width not in (1, 2, 4, 8)
            or flags not in (0, _SWAP, _NONZERO)
            or (flags == _NONZERO and width != 1)
        ):
            raise ValueError("run")
        if not _fits(in_at, count, in_step, width, input_size) or not _fits(
            out_at, count, out_step, width, output_size
        ):
            raise ValueError("run")
    return input_size, output_size, checks, runs, template, blob


def reference_move(program: bytes, data: bytes) -> bytes | None:
    input_size, _, checks, runs, template, blob = _parse(program)
    if len(data) != input_size:
        return None
    for kind, at, count, step, arg in checks:
        if kind == _EQUAL and data[at : at + count] != blob[arg : arg + count]:
            return None
        if kind == _AT_MOST and any(data[at + i * step] > arg for i in range(count)):
            return None
        if kind == _UTF8:
            try:
                data[at : at + count].decode("utf-8")
            except UnicodeDecodeError:
                return None
    out = bytearray(template)
    for in_at, out_at, count, in_step, out_step, width, flags in runs:
        for i in range(count):
            element = data[in_at + i * in_step : in_at + i * in_step + width]
            moved = (
                bytes([element[0] != 0])
                if flags == _NONZERO
                else element[::-1]
                if flags == _SWAP
                else element
            )
            out[out_at + i * out_step : out_at + i * out_step + width] = moved
    return bytes(out)


def _result(move: Callable[[bytes, bytes], bytes | None], program: bytes, data: bytes) -> bytes | None | str:
    try:
        return move(program, data)
    except ValueError:
        return "malformed"


@st.composite
def _place(draw: st.DrawFn, count: int, step: int, width: int, size: int, wild: bool) -> int:
    """Where `count` elements (`step` apart, `width` each) start: within `size` unless `wild`
    (then anywhere near it: a malformed program, mostly)."""
    room = size - ((count - 1) * step + width if count else 0)
    return draw(st.integers(0, size + 4) if wild or room < 0 else st.integers(0, room))


@st.composite
def programs_and_inputs(draw: st.DrawFn) -> tuple[bytes, bytes]:
    """A program and an input: 4 in 5 programs well formed (their inputs mostly of their size,
    their expected bytes mostly there: so that runs run), the others with anything near valid."""
    wild = draw(st.integers(0, 4)) == 0
    input_size, output_size = draw(st.integers(0, 40)), draw(st.integers(0, 40))
    data = bytearray(draw(st.binary(min_size=input_size, max_size=input_size)))
    checks: list[tuple[int, int, int, int, int]] = []
    blob = bytearray()
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.integers(0, 3 if wild else 2))
        count, step = draw(st.integers(0, 6)), draw(st.integers(0, 9))
        while count and not wild and not _fits(0, count, step if kind == _AT_MOST else 1, 1, input_size):
            count -= 1
        at = draw(_place(count, step if kind == _AT_MOST else 1, 1, input_size, wild))
        arg = draw(st.sampled_from([0, 1, 0x7F, 255, 256] if wild else [0, 1, 0x7F, 255]))
        if kind == _EQUAL:
            arg = len(blob) + draw(st.integers(0, 1) if wild else st.just(0))
            blob += (
                data[at : at + count]
                if draw(st.integers(0, 3))
                else draw(st.binary(min_size=count, max_size=count))
            )
        checks.append((kind, at, count, step, arg))
    runs = []
    for _ in range(draw(st.integers(0, 4))):
        count, in_step, out_step = draw(st.integers(0, 6)), draw(st.integers(0, 9)), draw(st.integers(0, 9))
        width = draw(st.sampled_from([1, 2, 4, 8, 3] if wild else [1, 2, 4, 8]))
        flags = draw(st.integers(0, 3 if wild else 2))
        if not wild:  # as many elements as fit
            width = 1 if flags == _NONZERO else width
            while count and not (_fits(0, count, in_step, width, input_size)
                                 and _fits(0, count, out_step, width, output_size)):  # fmt: skip
                count -= 1
        at_in = draw(_place(count, in_step, width, input_size, wild))
        runs.append(
            (
                at_in,
                draw(_place(count, out_step, width, output_size, wild)),
                count,
                in_step,
                out_step,
                width,
                flags,
            )
        )
    words = [input_size, output_size, len(checks), len(runs), *(w for row in (*checks, *runs) for w in row)]
    program = (
        struct.pack(f"={len(words)}I", *words)
        + draw(st.binary(min_size=output_size, max_size=output_size))
        + blob
    )
    program = program[: len(program) - draw(st.sampled_from([0, 1, 8] if wild else [0]))]
    data += draw(st.sampled_from([b""] * 9 + [b"\0"]))
    return program, bytes(data)


@given(programs_and_inputs())
@settings(max_examples=3000, deadline=None)
def test_random_programs_move_as_their_python_reading_says(case: tuple[bytes, bytes]) -> None:
    """Random programs over random inputs: the same bytes, the same None (does not fit), the same
    refusal of a malformed program (ValueError), and no read or write out of bounds (a crash)."""
    from viewer_bridge.lcmcodec._mover import move

    program, data = case
    assert _result(move, program, data) == _result(reference_move, program, data)


def test_the_mover_takes_any_buffer_and_refuses_what_is_not_one() -> None:
    from viewer_bridge.lcmcodec._mover import move

    # In 4 bytes, out 4: bytes 0..1 must be b"\x01\x02", byte 3 at most 1; two 2-byte values swapped.
    program = struct.pack("=4I", 4, 4, 2, 1) + struct.pack("=5I", _EQUAL, 0, 2, 1, 0)
    program += struct.pack("=5I", _AT_MOST, 3, 1, 1, 1) + struct.pack("=7I", 0, 0, 2, 2, 2, 2, _SWAP)
    program += b"\0" * 4 + b"\x01\x02"  # the template, the expected bytes
    assert (
        move(program, b"\x01\x02\x03\x01")
        == b"\x02\x01\x01\x03"
        == reference_move(program, b"\x01\x02\x03\x01")
    )
    # unaligned
    assert move(memoryview(b"." + program)[1:], bytearray(b"\x01\x02\x03\x01")) == b"\x02\x01\x01\x03"
    assert move(MoveProgram(program), memoryview(b"\x01\x02\x03\x01")) == b"\x02\x01\x01\x03"
    assert move(program, b"\x01\x02\x03\x02") is None and move(program, b"\x01\x03\x03\x01") is None
    assert move(program, b"\x01\x02\x03") is None and move(program, b"\x01\x02\x03\x01\x00") is None
    with pytest.raises(TypeError):
        move(program, "text")  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        move(program)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="malformed move program"):
        move(program[:-7], b"\x01\x02\x03\x01")


# --- built, used, and the same bytes as the generated code -----------------------------------------------


def test_the_compiled_mover_is_built_and_used_here() -> None:
    """This checkout is installed with its build hook (or `python hatch_build.py` ran): the
    extension imports, and a kept layout is its program. No silent fallback to Python here."""
    built = importlib.import_module("viewer_bridge.lcmcodec._mover")
    assert built.move is not None
    assert layout.COMPILED_MOVER
    source = Path(layout.__file__).with_name("_mover.c")
    assert Path(built.__file__).stat().st_mtime >= source.stat().st_mtime, (
        "stale build: run python hatch_build.py"
    )
    status = TypeLibrary.load().get("drake.lcmt_iiwa_status")
    data = _status(7).encode()
    assert status.to_cdr(data) == status.to_cdr(data)
    assert type(status.transcoder.layouts[len(data)]) is MoveProgram


def _status(joints: int) -> Any:
    message = drake.lcmt_iiwa_status()
    message.utime, message.num_joints = 1_700_000_000_000_000, joints
    for index, name in enumerate(message.__slots__[2:]):
        setattr(message, name, [index + joint / 8 for joint in range(joints)])
    return message


def _command(joints: int, torques: int) -> Any:
    message = drake.lcmt_iiwa_command()
    message.utime, message.num_joints, message.num_torques = 5, joints, torques
    message.joint_position = [joint / 4 for joint in range(joints)]
    message.joint_torque = [-joint / 2 for joint in range(torques)]
    return message


def _shape_bytes(program: bytes) -> list[int]:
    """The input positions the program compares with what they were (its EQUAL checks)."""
    _, _, checks, _, _, _ = _parse(program)
    return [at + i for kind, at, count, _, _ in checks if kind == _EQUAL for i in range(count)]


def _assert_agrees(kept: Callable[[bytes], bytes], generated: Callable[[bytes], bytes], data: bytes) -> None:
    assert outcome(kept, data) == outcome(generated, data)


def _assert_guarded(keeper: Any, kept: Callable[[bytes], bytes], data: bytes) -> None:
    """`data` (of a kept layout) truncated, or any byte of a shape value altered, or a count
    claiming 2^31 elements: the generated code's own error, as without a layout."""
    generated = keeper.generated
    assert kept(data) == generated(data)
    found = keeper.layouts[len(data)]
    assert found is not None
    for cut in (1, 4, 8, len(data) - 1):
        assert isinstance(outcome(kept, data[:-cut]), str)  # a DecodeError's text
        _assert_agrees(kept, generated, data[:-cut])
    positions = _shape_bytes(found) if type(found) is MoveProgram else range(len(data))
    assert len(positions) >= 8  # the fingerprint or header at least
    for at in positions:
        for value in (data[at] ^ 0xFF, data[at] ^ 0x01):
            altered = data[:at] + bytes([value]) + data[at + 1 :]
            _assert_agrees(kept, generated, altered)
            if type(found) is MoveProgram:
                assert isinstance(outcome(kept, altered), str), at  # every shape value guards the layout
    assert kept(data) == generated(data)


@pytest.mark.usefixtures("mover")
def test_iiwa_status_to_cdr_gives_the_generated_codes_bytes() -> None:
    """lcmt_iiwa_status as its joint count changes (each size learnt, then met), damaged where its
    shape is: the kept layouts' bytes or errors are the generated code's."""
    status = TypeLibrary.load().get("drake.lcmt_iiwa_status")
    keeper = status.transcoder
    for joints in (7, 7, 0, 3, 7, 12, 3, 0):
        data = _status(joints).encode()
        assert status.to_cdr(data) == keeper.generated(data) == status.to_cdr(data)
    assert len(keeper.layouts) == 4
    data = _status(7).encode()
    _assert_guarded(keeper, status.to_cdr, data)
    huge = data[:16] + struct.pack(">i", -(1 << 31)) + data[20:]  # num_joints
    assert isinstance(outcome(status.to_cdr, huge), str)
    _assert_agrees(status.to_cdr, keeper.generated, huge)


@pytest.mark.usefixtures("mover")
def test_cdr_to_iiwa_command_gives_the_generated_codes_bytes() -> None:
    """CDR -> lcmt_iiwa_command, as its joint and torque counts change, damaged where its shape
    is (the header, both length fields, both sequence counts), or a count claiming 2^31."""
    command = TypeLibrary.load().get("drake.lcmt_iiwa_command")
    keeper = command.encoder
    for joints, torques in ((7, 7), (7, 7), (7, 0), (6, 8), (0, 0), (7, 7)):
        lcm = _command(joints, torques).encode()
        cdr = command.to_cdr(lcm)
        assert command.from_cdr(cdr) == lcm == keeper.generated(cdr) == command.from_cdr(cdr)
    cdr = command.to_cdr(_command(7, 7).encode())
    _assert_guarded(keeper, command.from_cdr, cdr)
    count = cdr.index(struct.pack("<I", 7), 4 + 12)  # joint_position's count, after utime and num_joints
    huge = cdr[:count] + struct.pack("<I", 1 << 31) + cdr[count + 4 :]
    assert isinstance(outcome(command.from_cdr, huge), str)
    _assert_agrees(command.from_cdr, keeper.generated, huge)


def test_a_program_beyond_its_bound_leaves_the_python_movers_bounds_to_say(tmp_path: Path) -> None:
    """2000 one-letter strings: a program of more than `PROGRAM_BYTES`; no program is kept, and the
    bytes are the generated code's both ways."""
    (tmp_path / "words.lcm").write_text("package words; struct words_t { int32_t n; string words[n]; }")
    words = TypeLibrary.load([str(tmp_path / "words.lcm")], drake=False).get("words.words_t")
    lcm = (
        words.packed_fingerprint
        + struct.pack(">i", 2000)
        + b"".join(struct.pack(">I2s", 2, b"a\0") for _ in range(2000))
    )
    cdr = words.transcoder.generated(lcm)
    assert words.to_cdr(lcm) == words.to_cdr(lcm) == cdr and words.from_cdr(cdr) == words.from_cdr(cdr) == lcm
    assert type(words.transcoder.layouts[len(lcm)]) is not MoveProgram
    assert type(words.encoder.layouts[len(cdr)]) is not MoveProgram


# --- the build hook -----------------------------------------------------------------------------------------


def test_the_build_hook_compiles_a_module_that_moves(tmp_path: Path) -> None:
    target = tmp_path / hatch_build.extension_path(tmp_path).name
    assert hatch_build.compile_mover(ROOT / hatch_build.SOURCE, target) is None
    spec = importlib.util.spec_from_file_location("_mover", target)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    program = struct.pack("=4I", 2, 2, 0, 1) + struct.pack("=7I", 0, 0, 1, 2, 2, 2, _SWAP) + b"\0\0"
    assert module.move(program, b"\x01\x02") == b"\x02\x01"


def test_without_a_compiler_the_build_warns_and_stays_pure_python(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A compiler that fails (`CC=/bin/false`) or is missing: one warning naming the command, no
    module left behind, a pure-Python wheel (the Python movers give the same bytes)."""
    (tmp_path / hatch_build.SOURCE).parent.mkdir(parents=True)
    (tmp_path / hatch_build.SOURCE).write_bytes((ROOT / hatch_build.SOURCE).read_bytes())
    hatch_build.extension_path(tmp_path).write_bytes(b"stale")
    warnings: list[str] = []

    class App:
        def display_warning(self, message: str) -> None:
            warnings.append(message)

    for compiler in ("/bin/false", str(tmp_path / "no-such-cc")):
        monkeypatch.setenv("CC", compiler)
        hook = hatch_build.MoverBuildHook(str(tmp_path), {}, None, None, str(tmp_path), "wheel", App())  # type: ignore[arg-type]
        build_data: dict[str, Any] = {"pure_python": True, "force_include": {}}
        hook.initialize("standard", build_data)
        assert build_data == {"pure_python": True, "force_include": {}}
        assert not hatch_build.extension_path(tmp_path).exists()
    assert len(warnings) == 2 and all("not compiled" in w and "pure-Python" in w for w in warnings)
    assert "/bin/false" in warnings[0] and "no-such-cc" in warnings[1]


def test_a_transcoders_kept_programs_move_in_one_call_or_say_none() -> None:
    """`LayoutKeeper.kept` (the express path's transcoder): a message of a kept size gives the
    generated code's bytes; one of a size not kept, of a shape value altered, or not bytes, None
    (the caller then converts it as usual); programs of another kind than a dict, a TypeError."""
    from viewer_bridge.lcmcodec._mover import move_kept

    status = TypeLibrary.load().get("drake.lcmt_iiwa_status")
    keeper = status.transcoder
    seven = _status(7).encode()
    status.to_cdr(seven)
    kept = keeper.kept()
    assert kept is not None and kept(seven) == keeper.generated(seven)
    assert kept(_status(5).encode()) is None  # a size not kept yet
    for at in _shape_bytes(keeper.layouts[len(seven)]):  # type: ignore[arg-type]
        assert kept(seven[:at] + bytes([seven[at] ^ 0xFF]) + seven[at + 1 :]) is None, at
    assert kept(bytearray(seven)) is None  # type: ignore[arg-type]
    assert move_kept({len(seven): None}, seven) is None and move_kept({len(seven): (1, 2)}, seven) is None
    with pytest.raises(TypeError):
        move_kept([], seven)  # type: ignore[arg-type]
