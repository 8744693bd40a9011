"""Tree viewer requests -> a scene: `TreeState` applies requests to a tree, answers them as
Director does (MISSING_PATHS included), and reads the tree back as a scene."""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from viewer_bridge.errors import RequestRejected, SceneError
from viewer_bridge.formats.tree_viewer.commands import geometry_from_command, pose_from_transform
from viewer_bridge.formats.tree_viewer.common import JsonObject
from viewer_bridge.formats.tree_viewer.envelope import (
    ERROR_HANDLING_REQUEST,
    ERROR_UNKNOWN_REQUEST_TYPE,
    MISSING_PATHS,
    OK,
    Request,
    echo_time,
    request_timestamp,
)
from viewer_bridge.model.scene import Geometry, Link, LinkPoses, MeshFile, Pose, Scene

Path = tuple[str, ...]


@dataclass
class _Node:
    children: dict[str, _Node] = field(default_factory=dict)
    transform: Pose = Pose()
    geometries: list[Geometry] = field(default_factory=list)

    def has_geometry(self) -> bool:
        return bool(self.geometries) or any(child.has_geometry() for child in self.children.values())


_REQUEST_KEYS = {"timestamp", "utime", "setgeometry", "settransform", "delete"}


class TreeState:
    """A tree viewer's tree: apply requests to it, read it back as a scene.

    A request is checked as a whole before anything is applied; then `delete` goes first, then
    `setgeometry`, then `settransform`. A settransform for a path with no geometry at or below
    it is reported as MISSING_PATHS, as Director does. `mesh_file` paths must lie below one of
    `mesh_roots` (no roots: no mesh files), since a viewer should not be told to read any file.
    """

    def __init__(self, mesh_roots: Sequence[str | os.PathLike[str]] = ()) -> None:
        self.root = _Node()
        self.timestamp_us = 0
        self.mesh_roots = [os.path.realpath(root) for root in mesh_roots]

    def respond(self, request: JsonObject) -> JsonObject:
        """Apply one request and answer it: status 0 or 1, or -3 / -4 with an `error` text."""
        try:
            return self.apply(request)
        except RequestRejected as error:
            return {"timestamp": echo_time(request), "status": error.status, "error": str(error)}
        except SceneError as error:
            return {"timestamp": echo_time(request), "status": ERROR_HANDLING_REQUEST, "error": str(error)}

    def apply(self, request: JsonObject) -> JsonObject:
        """Apply one request; returns the response payload (status, missing_paths). When it raises,
        the tree is unchanged.

        Raises:
            RequestRejected: an unknown command (status -4).
            SceneError: a bad command (status -3).
        """
        unknown = sorted(set(request) - _REQUEST_KEYS)
        if unknown:
            raise RequestRejected(ERROR_UNKNOWN_REQUEST_TYPE, f"unknown command {unknown[0]!r}")
        timestamp = request_timestamp(request)
        if timestamp != echo_time(request):
            raise SceneError(f"timestamp must be an integer of microseconds, got {timestamp!r}")
        deletes = [
            _path(command, f"delete[{index}]") for index, command in enumerate(_commands(request, "delete"))
        ]
        geometries = [
            self._geometry_command(command, f"setgeometry[{index}]")
            for index, command in enumerate(_commands(request, "setgeometry"))
        ]
        transforms = []
        for index, command in enumerate(_commands(request, "settransform")):
            where = f"settransform[{index}]"
            transform = command.get("transform", {}) if isinstance(command, dict) else None
            transforms.append((_path(command, where), pose_from_transform(transform, f"{where}.transform")))
        for path in deletes:
            self._delete(path)
        for path, parsed in geometries:
            self._node(path, create=True).geometries = parsed
        missing = []
        for path, pose in transforms:
            node = self._node(path, create=True)
            node.transform = pose
            if not node.has_geometry():
                missing.append(list(path))
        self.timestamp_us = timestamp
        response: dict[str, Any] = {"timestamp": timestamp, "status": MISSING_PATHS if missing else OK}
        if missing:
            response["missing_paths"] = missing
        return response

    def _geometry_command(self, command: Any, where: str) -> tuple[Path, list[Geometry]]:
        path = _path(command, where)
        items = command.get("geometries", [command["geometry"]] if "geometry" in command else None)
        if not isinstance(items, list):
            raise SceneError(f"{where}: needs 'geometry' or 'geometries' (a list)")
        parsed = [geometry_from_command(item, f"{where}.geometry") for item in items]
        for geometry in parsed:
            if isinstance(geometry.shape, MeshFile):
                self._check_mesh_path(geometry.shape.path, where)
        return path, parsed

    def _check_mesh_path(self, path: str, where: str) -> None:
        try:
            real = os.path.realpath(path)
        except ValueError as error:  # e.g. an embedded NUL
            raise SceneError(f"{where}: mesh_file {path!r} is not a valid path ({error})") from None
        if not any(os.path.commonpath([real, root]) == root for root in self.mesh_roots):
            allowed = ", ".join(self.mesh_roots) or "none configured"
            raise SceneError(f"{where}: mesh_file {path} is outside the allowed folders ({allowed})")

    def _node(self, path: Path, create: bool) -> _Node:
        node = self.root
        for name in path:
            if name not in node.children:
                if not create:
                    raise KeyError(name)
                node.children[name] = _Node()
            node = node.children[name]
        return node

    def _delete(self, path: Path) -> None:
        if not path:
            self.root = _Node()
            return
        try:
            parent = self._node(path[:-1], create=False)
        except KeyError:
            return
        parent.children.pop(path[-1], None)

    def scene(self) -> Scene:
        """The tree as a scene: each node holding geometry becomes (part of) a link.

        A geometry at path P belongs to the link P[:-1] (its parent node), whose pose is the
        composition of the transforms from the root; the transform at P itself is folded into
        the geometry's pose. Links laid out as `load_requests` does ([..., robot_num, name])
        get their name and robot_num back; any other path is joined with `::`.
        """
        links: dict[Path, list[Geometry]] = {}
        link_poses: dict[Path, Pose] = {}
        self._collect(self.root, (), Pose(), Pose(), links, link_poses)
        scene_links, names, robot_nums, positions, quaternions = [], [], [], [], []
        for path, geometries in links.items():
            name, robot_num = _link_identity(path)
            scene_links.append(Link(name, robot_num, tuple(geometries)))
            names.append(name)
            robot_nums.append(robot_num)
            positions.append(link_poses[path].position)
            quaternions.append(link_poses[path].quaternion_wxyz)
        poses = LinkPoses(
            self.timestamp_us // 1000,
            tuple(names),
            np.asarray(robot_nums, dtype=np.int32),
            np.asarray(positions, dtype=np.float64).reshape(-1, 3),
            np.asarray(quaternions, dtype=np.float64).reshape(-1, 4),
        )
        return Scene(tuple(scene_links), poses)

    def _collect(
        self,
        node: _Node,
        path: Path,
        parent_pose: Pose,
        pose: Pose,
        links: dict[Path, list[Geometry]],
        link_poses: dict[Path, Pose],
    ) -> None:
        if node.geometries:
            link = path[:-1]
            links.setdefault(link, [])
            link_poses[link] = parent_pose
            for geometry in node.geometries:
                local = node.transform.compose(geometry.pose)
                links[link].append(Geometry(geometry.shape, local, geometry.color))
        for name, child in node.children.items():
            self._collect(child, (*path, name), pose, pose.compose(child.transform), links, link_poses)


def _link_identity(path: Path) -> tuple[str, int]:
    if len(path) >= 2 and path[-2].lstrip("-").isdigit():
        return path[-1], int(path[-2])
    return "::".join(path), 0


def _commands(request: Request, key: str) -> list[Any]:
    commands = request.get(key, [])
    if not isinstance(commands, list):
        raise SceneError(f"{key} is not a list")
    for index, command in enumerate(commands):
        if not isinstance(command, dict):
            raise SceneError(f"{key}[{index}] is not an object")
    return commands


def _path(command: Any, where: str) -> Path:
    path = command.get("path")
    if not isinstance(path, list) or not all(isinstance(part, str) for part in path):
        raise SceneError(f"{where}.path must be a list of strings")
    return tuple(path)


def scene_from_requests(
    requests: Iterable[Request], mesh_roots: Sequence[str | os.PathLike[str]] = ()
) -> Scene:
    """Apply requests to an empty tree and read the scene back."""
    state = TreeState(mesh_roots)
    for request in requests:
        state.apply(request)
    return state.scene()


__all__ = ["TreeState", "scene_from_requests"]
