"""The Foxglove message types the bridge writes, and their protobuf schemas as channels and MCAP
files carry them. Transports use this module (it knows no scene)."""

from __future__ import annotations

import importlib
from functools import cache

SCENE_UPDATE = "foxglove.SceneUpdate"
FRAME_TRANSFORMS = "foxglove.FrameTransforms"
RAW_IMAGE = "foxglove.RawImage"
COMPRESSED_IMAGE = "foxglove.CompressedImage"
CAMERA_CALIBRATION = "foxglove.CameraCalibration"


@cache
def schema(type_name: str) -> bytes:
    """A foxglove type's protobuf schema as Foxglove and MCAP carry it: a serialized
    FileDescriptorSet of its .proto file and everything that file imports."""
    from google.protobuf import descriptor_pb2, descriptor_pool
    from google.protobuf.descriptor import FileDescriptor

    importlib.import_module(f"foxglove_schemas_protobuf.{type_name.removeprefix('foxglove.')}_pb2")
    root = descriptor_pool.Default().FindMessageTypeByName(type_name).file
    files: dict[str, FileDescriptor] = {}

    def add(file: FileDescriptor) -> None:
        for dependency in file.dependencies:
            add(dependency)
        if file.name not in files:
            files[file.name] = file

    add(root)
    descriptor_set = descriptor_pb2.FileDescriptorSet()
    for file in files.values():
        file.CopyToProto(descriptor_set.file.add())
    return descriptor_set.SerializeToString()
