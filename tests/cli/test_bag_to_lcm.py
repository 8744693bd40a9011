"""`viewer-bridge convert BAG OUT.lcmlog`: a ROS 2 bag (MCAP by mcap-ros2-support, rosbag2 folder)
into an LCM log that lcm-gen's Python reads back to the bag's values."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.lcmcodec.ros_bag import SAMPLES, lcmgen_decode, typestore, write_bag
from tests.lcmcodec.test_from_ros import lcm_gen_all
from tests.lcmcodec.test_ros_cdr import serialized
from viewer_bridge.cli.bag_to_lcm import bag_to_lcm
from viewer_bridge.cli.main import main
from viewer_bridge.lcmcodec.from_ros import lcm_channel, load_ros_definitions, map_ros_types
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders
from viewer_bridge.transports.lcm import read_log

JOINTS = SAMPLES[0][2]


def test_a_bag_becomes_an_lcm_log_lcm_gen_reads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_bag(tmp_path / "bag.mcap")
    out, types = tmp_path / "out.lcmlog", tmp_path / "types"
    assert main(["convert", str(tmp_path / "bag.mcap"), str(out), "--lcm-types-out", str(types)]) == 0
    printed = capsys.readouterr().out
    assert "       2  /joint_states -> joint_states" in printed and "/camera/image -> camera/image" in printed
    events = list(read_log(out))
    assert [event.channel for event in events] == [lcm_channel(topic) for topic, _, _ in SAMPLES]
    assert [event.timestamp_us for event in events] == [
        1_000_000 + index * 1000 for index in range(len(SAMPLES))
    ]
    assert lcm_gen_all(types, tmp_path / "gen").returncode == 0
    decoded = lcmgen_decode(tmp_path / "gen" / "py", [("sensor_msgs.JointState", events[0].data),
                                                      ("my_robot.Gripper", events[-1].data)])  # fmt: skip
    assert decoded[0]["name"] == JOINTS["name"] and decoded[0]["effort"] == JOINTS["effort"]
    assert decoded[1]["fingers"][1]["name"] == "thumb" and decoded[1]["ticks"] == 4_294_967_295
    # exists: not replaced without --force
    assert main(["convert", str(tmp_path / "bag.mcap"), str(out)]) == 2


def test_topics_narrow_and_unmappable_and_bad_messages_are_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mcap.writer import Writer

    store = typestore()
    bag = tmp_path / "mixed.mcap"
    with bag.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2")
        clash = writer.register_schema("lab/msg/Clash", "ros2msg", b"float64[] x\nint32 x_length\n")
        garbled = writer.register_schema("lab/msg/Garbled", "ros2msg", b"float64[ x\n")
        msgdef = store.generate_msgdef("sensor_msgs/msg/JointState", ros_version=2)[0]
        joints = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", msgdef.encode())
        channels = {topic: writer.register_channel(topic, "cdr", schema) for topic, schema in
                    [("/clash", clash), ("/joints", joints), ("/other", joints), ("/garbled", garbled)]}  # fmt: skip
        good = serialized("sensor_msgs/msg/JointState", JOINTS)
        for index, (topic, data) in enumerate([("/clash", b"\x00\x01\x00\x00"), ("/joints", good),
                                               ("/joints", good[:-3]), ("/other", good), ("/joints", good)]):  # fmt: skip
            writer.add_message(channels[topic], log_time=index * 1000, data=data, publish_time=index * 1000)
        writer.finish()
    result = bag_to_lcm(bag, tmp_path / "out.lcmlog", topics="/(clash|joints|garbled)")
    assert "x_length would collide" in result.skipped["/clash"]
    assert "lab/msg/Garbled: its recorded definition does not parse" in result.skipped["/garbled"]
    assert result.written == {"/joints": 2} and result.bad == {"/joints": 1}
    assert "sensor_msgs/msg/JointState.effort" in result.first_error["/joints"]
    assert [event.channel for event in read_log(tmp_path / "out.lcmlog")] == ["joints", "joints"]
    assert main(["convert", str(bag), str(tmp_path / "all.lcmlog")]) == 0
    printed = capsys.readouterr()
    assert "       1  /other -> other" in printed.out
    assert "viewer-bridge convert: /clash left out: lab/msg/Clash: field x's length field" in printed.err
    assert "/joints: 1 messages did not convert, the first: sensor_msgs/msg/JointState.effort" in printed.err


def test_a_rosbag2_folder_converts_too(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Writer

    store = typestore()
    with Writer(tmp_path / "bag", version=9) as writer:
        connection = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        writer.write(connection, 42_000, serialized("sensor_msgs/msg/JointState", JOINTS))
    result = bag_to_lcm(tmp_path / "bag", tmp_path / "out.lcmlog")
    assert result.written == {"/joint_states": 1}
    [event] = read_log(tmp_path / "out.lcmlog")
    assert (event.channel, event.timestamp_us) == ("joint_states", 42)


def joint_states_mcap(path: Path, count: int) -> None:
    """`count` JointStates a millisecond apart, in chunks of a few dozen messages."""
    from mcap_ros2.writer import Writer

    store = typestore()
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=2048)
        schema = writer.register_msgdef("sensor_msgs/msg/JointState",
                                        store.generate_msgdef("sensor_msgs/msg/JointState", ros_version=2)[0])  # fmt: skip
        for index in range(count):
            message = {**JOINTS, "position": [float(index), 0.0, 0.0]}
            writer.write_message("/joint_states", schema, message, log_time=index * 1_000_000, publish_time=0)
        writer.finish()


def converted(out: Path) -> list[int]:
    """The log's event times, in milliseconds (the bag's message indices)."""
    return [event.timestamp_us // 1000 for event in read_log(out)]


def damage_line(stderr: str) -> str:
    [line] = [line for line in stderr.splitlines() if "is damaged" in line]
    return line


def test_an_mcap_cut_mid_chunk_converts_its_whole_chunks_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mcap.reader import make_reader

    whole = tmp_path / "whole.mcap"
    joint_states_mcap(whole, 300)
    with whole.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and len(summary.chunk_indexes) > 4
    chunk = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole.read_bytes()[: chunk.chunk_start_offset + chunk.chunk_length // 2])
    assert main(["convert", str(cut), str(tmp_path / "out.lcmlog")]) == 1
    before = chunk.message_start_time // 1_000_000  # the messages of the chunks before the cut one
    assert converted(tmp_path / "out.lcmlog") == list(range(before))
    line = damage_line(capsys.readouterr().err)
    assert "cut.mcap: the file ends inside a record" in line and "cut short" in line
    assert f"the {before} messages before it are converted" in line and "Traceback" not in line


def rosbag2_db3(folder: Path, count: int) -> Path:
    from rosbags.rosbag2 import Writer

    data = serialized("sensor_msgs/msg/JointState", JOINTS)
    with Writer(folder, version=9) as writer:
        connection = writer.add_connection(
            "/joint_states", "sensor_msgs/msg/JointState", typestore=typestore()
        )
        for index in range(count):
            writer.write(connection, index * 1_000_000, data)
    [database] = folder.glob("*.db3")
    return database


def test_a_db3_with_a_damaged_page_converts_the_rows_before_it_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    database = rosbag2_db3(tmp_path / "bag", 2000)
    data = bytearray(database.read_bytes())
    middle = len(data) // 2 // 4096 * 4096  # a page of the messages' table (SQLite's pages are 4 KiB)
    data[middle : middle + 4096] = b"\xff" * 4096
    database.write_bytes(bytes(data))
    assert main(["convert", str(tmp_path / "bag"), str(tmp_path / "out.lcmlog")]) == 1
    times = converted(tmp_path / "out.lcmlog")
    assert 0 < len(times) < 2000 and times == list(range(len(times)))
    line = damage_line(capsys.readouterr().err)
    assert f"{database.name}: DatabaseError: database disk image is malformed" in line
    assert f"the {len(times)} messages before it are converted, the rest is lost" in line


def test_a_db3_row_that_holds_no_message_is_counted_and_the_rest_converts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import sqlite3

    database = rosbag2_db3(tmp_path / "bag", 20)
    with sqlite3.connect(database) as connection:
        connection.execute("UPDATE messages SET data = 'not bytes' WHERE id = 5")
    assert main(["convert", str(tmp_path / "bag"), str(tmp_path / "out.lcmlog")]) == 1
    assert converted(tmp_path / "out.lcmlog") == [index for index in range(20) if index != 4]
    [line] = [line for line in capsys.readouterr().err.splitlines() if "damaged" in line]
    assert (
        "/joint_states: 1 rows of the bag are damaged, the first: a row holds int 4000000 as its time and str"
        in line
    )


def test_a_bag_with_nothing_readable_is_refused_with_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = tmp_path / "whole.mcap"
    joint_states_mcap(whole, 3)
    (tmp_path / "stub.mcap").write_bytes(whole.read_bytes()[:12])
    assert main(["convert", str(tmp_path / "stub.mcap"), str(tmp_path / "out.lcmlog")]) == 2
    assert "stub.mcap holds no CDR topic that can be read" in capsys.readouterr().err
    assert not (tmp_path / "out.lcmlog").exists()


def joints_mcap_as(path: Path, compression: str, count: int, chunk_size: int = 2048) -> None:
    """`count` JointStates by mcap's own writer, chunks compressed as `compression` ("" for none,
    "unchunked" for messages outside any chunk)."""
    from mcap.writer import CompressionType, Writer

    data = serialized("sensor_msgs/msg/JointState", JOINTS)
    msgdef = typestore().generate_msgdef("sensor_msgs/msg/JointState", ros_version=2)[0]
    kind = {"": CompressionType.NONE, "lz4": CompressionType.LZ4, "zstd": CompressionType.ZSTD}
    with path.open("wb") as stream:
        writer = Writer(stream, compression=kind.get(compression, CompressionType.NONE),
                        use_chunking=compression != "unchunked", chunk_size=chunk_size)  # fmt: skip
        writer.start(profile="ros2")
        schema = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", msgdef.encode())
        channel = writer.register_channel("/joint_states", "cdr", schema)
        for index in range(count):
            writer.add_message(channel, log_time=index * 1_000_000, data=data, publish_time=0)
        writer.finish()


@pytest.mark.parametrize("compression", ["", "lz4", "zstd", "unchunked"])
def test_mcap_chunks_of_every_compression_and_none_read_alike(tmp_path: Path, compression: str) -> None:
    joints_mcap_as(tmp_path / "bag.mcap", compression, 50)
    result = bag_to_lcm(tmp_path / "bag.mcap", tmp_path / "out.lcmlog")
    assert result.complete and result.written == {"/joint_states": 50}
    events = list(read_log(tmp_path / "out.lcmlog"))
    assert [event.timestamp_us // 1000 for event in events] == list(range(50))
    definitions, wanted = load_ros_definitions(["sensor_msgs/msg/JointState"])
    encoder = compile_ros_encoders(map_ros_types(definitions, wanted), wanted)["sensor_msgs/msg/JointState"]
    assert {event.data for event in events} == {
        encoder.encode(serialized("sensor_msgs/msg/JointState", JOINTS))
    }


def test_a_chunk_whose_crc_does_not_match_is_skipped_and_the_rest_converts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mcap.reader import make_reader

    joints_mcap_as(tmp_path / "bag.mcap", "", 200)
    data = bytearray((tmp_path / "bag.mcap").read_bytes())
    with (tmp_path / "bag.mcap").open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[2]
    data[chunk.chunk_start_offset + chunk.chunk_length - 20] ^= 0xFF  # inside a message's numbers
    (tmp_path / "bad.mcap").write_bytes(bytes(data))
    assert main(["convert", str(tmp_path / "bad.mcap"), str(tmp_path / "out.lcmlog")]) == 1
    first, last = chunk.message_start_time // 1_000_000, chunk.message_end_time // 1_000_000
    assert converted(tmp_path / "out.lcmlog") == [*range(first), *range(last + 1, 200)]
    err = capsys.readouterr().err
    assert (
        f"1 chunks are damaged and skipped, the first: bad.mcap: the chunk at byte {chunk.chunk_start_offset}: "
        "its CRC-32 does not match its records"
    ) in err and "Traceback" not in err


def zstd_bomb(inflated: int) -> bytes:
    """A zstd frame that inflates to `inflated` zero bytes (a multiple of 128 KiB) from 4 bytes per
    128 KiB: run-length blocks (RFC 8878: a block header of 3 bytes, then the one byte repeated)."""
    block = 128 * 1024
    frame = bytearray(b"\x28\xb5\x2f\xfd\x00\x38")  # magic; no content size; a 128 KiB window
    count = inflated // block
    for index in range(count):
        last = index == count - 1
        frame += ((block << 3) | (1 << 1) | last).to_bytes(3, "little") + b"\x00"
    return bytes(frame)


def mcap_with_bomb(path: Path, compression: str, bomb: bytes) -> tuple[int, int]:
    """200 JointStates in uncompressed chunks, the third chunk replaced by one that declares 100
    bytes and holds `bomb` compressed as `compression`; the first and last message time (ms) lost."""
    import struct

    from mcap.reader import make_reader

    joints_mcap_as(path, "", 200)
    data = path.read_bytes()
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[2]
    name = compression.encode()
    body = struct.pack("<QQQI", 0, 0, 100, 0) + struct.pack("<I", len(name)) + name
    body += struct.pack("<Q", len(bomb)) + bomb
    record = struct.pack("<BQ", 0x06, len(body)) + body
    start, end = chunk.chunk_start_offset, chunk.chunk_start_offset + chunk.chunk_length
    path.write_bytes(data[:start] + record + data[end:])
    return chunk.message_start_time // 1_000_000, chunk.message_end_time // 1_000_000


def test_a_chunk_that_inflates_past_its_declared_size_costs_no_memory_and_is_skipped(tmp_path: Path) -> None:
    """Issue 51 row 5: a 49 KB MCAP whose zstd chunk declares 100 bytes made `convert` hold 3.2 GB.
    Here a 16 KB chunk of 512 MiB: the convert process stays well under 200 MiB, says the chunk is
    damaged, converts the other chunks and exits 1."""
    import subprocess
    import sys

    first, last = mcap_with_bomb(tmp_path / "bomb.mcap", "zstd", zstd_bomb(512 << 20))
    assert (tmp_path / "bomb.mcap").stat().st_size < 64_000
    out = tmp_path / "out.lcmlog"
    # The peak is the process's own (VmHWM, its memory since exec): getrusage's would count the
    # pytest process it was forked from.
    convert = (
        "import sys; from viewer_bridge.cli.main import main; code = main(sys.argv[1:]); "
        "print(*[line for line in open('/proc/self/status') if line.startswith('VmHWM')], file=sys.stderr); "
        "sys.exit(code)"
    )
    command = [sys.executable, "-c", convert, "convert", str(tmp_path / "bomb.mcap"), str(out)]
    process = subprocess.run(command, capture_output=True, text=True, timeout=300)
    said = process.stderr
    assert process.returncode == 1, said
    [peak_kib] = [int(line.split()[1]) for line in said.splitlines() if line.startswith("VmHWM")]
    assert peak_kib < 200 * 1024, f"peak RSS {peak_kib // 1024} MiB"
    assert "1 chunks are damaged and skipped, the first: bomb.mcap: the chunk at byte " in said
    assert "it inflates past the 100 bytes it declares" in said and "Traceback" not in said
    assert converted(out) == [*range(first), *range(last + 1, 200)]


def test_an_lz4_chunk_is_inflated_no_further_than_its_declared_size(tmp_path: Path) -> None:
    """The lz4 half of row 5: 64 MiB of zeros in a chunk that declares 100 bytes is refused having
    inflated 101 bytes (Python's own allocations traced: far under the 64 MiB)."""
    import tracemalloc

    from lz4.frame import compress

    first, last = mcap_with_bomb(tmp_path / "bomb.mcap", "lz4", compress(bytes(64 << 20)))
    tracemalloc.start()
    try:
        result = bag_to_lcm(tmp_path / "bomb.mcap", tmp_path / "out.lcmlog")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20, f"peak {peak >> 20} MiB"
    assert not result.complete and result.cut is None
    [damage] = result.damaged_chunks
    assert damage.startswith("bomb.mcap: the chunk at byte ") and "inflates past the 100 bytes" in damage
    assert converted(tmp_path / "out.lcmlog") == [*range(first), *range(last + 1, 200)]


def test_a_rosbag2_folders_mcap_chunk_is_inflated_no_further_than_its_declared_size(tmp_path: Path) -> None:
    """rosbags inflates a folder's MCAP chunks whole: a folder whose file holds a chunk that
    inflates past its size is read by the bridge's own reader instead, within the same bound."""
    import tracemalloc

    from lz4.frame import compress
    from rosbags.rosbag2 import StoragePlugin, Writer

    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(
            "/joint_states", "sensor_msgs/msg/JointState", typestore=typestore()
        )
        writer.write(connection, 0, serialized("sensor_msgs/msg/JointState", JOINTS))
    [storage] = (tmp_path / "bag").glob("*.mcap")
    first, last = mcap_with_bomb(storage, "lz4", compress(bytes(64 << 20)))
    tracemalloc.start()
    try:
        result = bag_to_lcm(tmp_path / "bag", tmp_path / "out.lcmlog")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20, f"peak {peak >> 20} MiB"
    [damage] = result.damaged_chunks
    assert "inflates past the 100 bytes" in damage and not result.complete
    assert converted(tmp_path / "out.lcmlog") == [*range(first), *range(last + 1, 200)]


def big_joint_states_mcap(path: Path, count: int, joints: int, compressed: bool = True) -> None:
    """`count` JointStates of `joints` joints each (one CDR message, written again and again: quick
    to write, slow enough to convert that an interrupt comes midway), in zstd chunks or plain ones."""
    from mcap.writer import CompressionType, Writer

    store = typestore()
    message = {**JOINTS, "name": [f"joint{i}" for i in range(joints)], "position": [0.5] * joints,
               "velocity": [0.25] * joints, "effort": [1.0] * joints}  # fmt: skip
    data = serialized("sensor_msgs/msg/JointState", message)
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD if compressed else CompressionType.NONE)
        writer.start(profile="ros2")
        msgdef = store.generate_msgdef("sensor_msgs/msg/JointState", ros_version=2)[0]
        schema = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", msgdef.encode())
        channel = writer.register_channel("/joint_states", "cdr", schema)
        for index in range(count):
            writer.add_message(channel, log_time=index * 1000, data=data, publish_time=index * 1000)
        writer.finish()


def test_ctrl_c_during_a_bag_convert_keeps_a_readable_partial_log_and_no_real_name(tmp_path: Path) -> None:
    import sys

    from tests.cli.test_cli import interrupted_convert

    bag, out = tmp_path / "big.mcap", tmp_path / "out.lcmlog"
    partial = tmp_path / "out.lcmlog.partial"
    big_joint_states_mcap(bag, 100_000, 200)
    written = interrupted_convert(
        [sys.executable, "-m", "viewer_bridge", "convert", str(bag), str(out)], partial
    )
    assert len(list(read_log(partial))) == written < 100_000
    assert not out.exists()


def test_lcm_types_out_that_is_a_file_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_bag(tmp_path / "bag.mcap")
    afile, out = tmp_path / "afile", tmp_path / "out.lcmlog"
    afile.write_text("mine\n")
    assert main(["convert", str(tmp_path / "bag.mcap"), str(out), "--lcm-types-out", str(afile)]) == 2
    assert capsys.readouterr().err == (
        f"viewer-bridge convert: --lcm-types-out {afile}: {afile} is a file, not a folder: "
        "give a folder to write into\n"
    )
    assert afile.read_text() == "mine\n" and sorted(tmp_path.iterdir()) == [afile, tmp_path / "bag.mcap"]
    inside = afile / "types"  # a folder under a file cannot be made either
    assert main(["convert", str(tmp_path / "bag.mcap"), str(out), "--lcm-types-out", str(inside)]) == 2
    assert f"{afile}, in its path, is a file" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_rosbag2_folder_of_either_storage_converts_with_one_topic_list(
    storage: str, tmp_path: Path
) -> None:
    """A folder of either storage is read by the same reader as an MCAP file; a folder whose
    files rosbag2 compressed whole is opened by rosbags' reader instead, and converts the same."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    data = serialized("sensor_msgs/msg/JointState", JOINTS)
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    for name, whole_files in (("plain", False), ("compressed", True)):
        writer = Writer(tmp_path / name, version=9, storage_plugin=plugin)
        if whole_files:
            writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
        with writer:
            connection = writer.add_connection(
                "/joint_states", "sensor_msgs/msg/JointState", typestore=typestore()
            )
            for index in range(30):
                writer.write(connection, index * 1_000_000, data)
        assert main(["convert", str(tmp_path / name), str(tmp_path / f"{name}.lcmlog")]) == 0
        assert converted(tmp_path / f"{name}.lcmlog") == list(range(30))
    assert not list((tmp_path / "plain").glob("*.zstd")) and list((tmp_path / "compressed").glob("*.zstd"))


def test_a_stop_before_the_first_message_keeps_no_partial_log(tmp_path: Path) -> None:
    """As in the other direction: an LCM log with no event would look like a result."""
    import threading

    from viewer_bridge.errors import Interrupted

    bag, out = tmp_path / "bag.mcap", tmp_path / "out.lcmlog"
    joint_states_mcap(bag, 50)
    stop = threading.Event()
    stop.set()  # Ctrl-C came before the first message
    with pytest.raises(Interrupted, match=r"^interrupted: no message written yet: nothing kept$"):
        bag_to_lcm(bag, out, stop=stop)
    assert sorted(tmp_path.iterdir()) == [bag]


def test_the_bag_says_how_many_messages_its_chosen_topics_hold(tmp_path: Path) -> None:
    """The progress' total, without reading a message: an MCAP file's summary statistics, a
    `.db3`'s rows, per topic; an MCAP file cut short (no summary) does not say."""
    from collections import Counter

    from viewer_bridge.cli.bag_files import DirectReader

    write_bag(tmp_path / "bag.mcap")
    reader = DirectReader(tmp_path / "bag.mcap")
    recorded = Counter(topic for topic, _, _ in SAMPLES)
    assert {c.topic: reader.message_count([c]) for c in reader.connections} == recorded
    assert reader.message_count(reader.connections) == len(SAMPLES)
    rosbag2_db3(tmp_path / "folder", 30)
    assert (
        DirectReader(tmp_path / "folder").message_count(DirectReader(tmp_path / "folder").connections) == 30
    )
    joint_states_mcap(tmp_path / "whole.mcap", 300)
    assert (
        DirectReader(tmp_path / "whole.mcap").message_count(DirectReader(tmp_path / "whole.mcap").connections)
        == 300
    )
    data = (tmp_path / "whole.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) * 2 // 3])
    cut = DirectReader(tmp_path / "cut.mcap")
    assert cut.connections and cut.message_count(cut.connections) is None


def test_a_bag_convert_on_a_pipe_says_its_progress_per_tenth_of_the_chosen_topics(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import re

    from viewer_bridge.util import progress as progress_module

    monkeypatch.setattr(progress_module, "QUIET_S", 0.0)  # as if the conversion took long
    bag = tmp_path / "bag.mcap"
    write_bag(bag)
    assert len(SAMPLES) > 3 and sum(topic in ("/joint_states", "/imu") for topic, _, _ in SAMPLES) == 3
    bag_to_lcm(bag, tmp_path / "out.lcmlog", topics="/joint_states|/imu", progress=True)
    said = [re.sub(r" \(\d+ s\)$", "", line) for line in capsys.readouterr().err.splitlines()]
    assert said == [  # of the 3 messages of the topics chosen, not the bag's 7
        "viewer-bridge convert: converting: 30%: 1 of 3 messages",
        "viewer-bridge convert: converting: 60%: 2 of 3 messages",
        "viewer-bridge convert: converting: 100%: 3 of 3 messages",
    ]


def summary_at(path: Path) -> tuple[int, int]:
    """Where an MCAP file's summary section starts and ends (its footer's first field, and the
    summary offsets' start), by mcap.dev's layout: the footer record, then the end magic."""
    import struct

    data = path.read_bytes()
    start, offsets, _ = struct.unpack_from("<QQI", data, len(data) - 8 - 20)
    return start, offsets


def test_an_mcap_summary_past_the_bound_is_not_read_whole_and_the_records_give_the_messages(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A footer that says the summary starts at the file's first record (a summary of 70 MB):
    read whole, the reader would hold the file; it is refused by its size, said with the file's
    name, and the messages come from the records, a chunk at a time."""
    import struct
    import tracemalloc

    from viewer_bridge.cli.bag_files import DirectReader

    bag = tmp_path / "bag.mcap"
    big_joint_states_mcap(bag, 10_000, 200, compressed=False)
    data = bytearray(bag.read_bytes())
    assert len(data) > 64 << 20
    struct.pack_into("<QQ", data, len(data) - 8 - 20, 8, 0)  # the summary: from byte 8 to the footer
    bag.write_bytes(bytes(data))
    tracemalloc.start()
    try:
        reader = DirectReader(bag)
        read = sum(1 for _ in reader.messages(reader.connections))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert [c.topic for c in reader.connections] == ["/joint_states"] and read == 10_000
    assert peak < 16 << 20, peak  # a chunk of 1 MiB at a time, not the 70 MB "summary"
    [why] = reader.unread_summaries
    summary = len(data) - 8 - 20 - 9 - 8
    assert why == (
        f"bag.mcap: its summary section of {summary} bytes (from byte 8) is past the 64 MiB read whole: "
        "its records are read instead"
    )
    assert reader.message_count(reader.connections) is None  # no total: the statistics were not read
    out = tmp_path / "out.lcmlog"
    assert main(["convert", str(bag), str(out), "--topics", "/joint_states"]) == 0  # nothing lost
    assert f"{bag}: {why}" in capsys.readouterr().err
    assert sum(1 for _ in read_log(out)) == 10_000


def test_an_mcap_statistics_record_that_claims_more_than_it_holds_gives_no_total_and_loses_nothing(
    tmp_path: Path,
) -> None:
    """A Statistics record whose per-channel counts claim 4 GiB in a file of a few KB: the summary
    is not trusted (no total), and every message is read from the records."""
    import struct

    from viewer_bridge.cli.bag_files import DirectReader

    bag = tmp_path / "bag.mcap"
    joints_mcap_as(bag, "", 200)
    data = bytearray(bag.read_bytes())
    at, end = summary_at(bag)
    found = []
    while at < end:  # the summary's records: opcode, uint64 length, content
        op, length = struct.unpack_from("<BQ", data, at)
        if op == 0x0B:  # Statistics: 42 bytes of counts and times, then the per-channel map's length
            found.append(at)
            struct.pack_into("<I", data, at + 9 + 42, 0xFFFF_FFFF)
        at += 9 + length
    assert len(found) == 1
    assert DirectReader(bag).message_count(DirectReader(bag).connections) == 200  # before
    bag.write_bytes(bytes(data))
    reader = DirectReader(bag)
    assert [c.topic for c in reader.connections] == ["/joint_states"] and not reader.unread_summaries
    assert reader.message_count(reader.connections) is None
    assert sum(1 for _ in reader.messages(reader.connections)) == 200
    result = bag_to_lcm(bag, tmp_path / "out.lcmlog")
    assert result.complete and result.written == {"/joint_states": 200}
