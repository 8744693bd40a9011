"""ROS 2's rules for topic names, namespaces and node names, checked when a config loads.

The rules are rcl's and rmw's (rcl/validate_topic_name.h, rmw/validate_full_topic_name.h,
rmw/validate_namespace.h, rmw/validate_node_name.h): a name rclpy would refuse at its first
publish is refused here, with the reason, before the bridge starts. Pure Python, so that a
config is checked on a machine without the ROS 2 wheels too; tests hold it to rclpy's own checks.
Each function returns what is wrong, or None for a valid name.
"""

from __future__ import annotations

import re
import threading

from viewer_bridge.errors import Held

_TOPIC_CHARACTERS = re.compile(r"[A-Za-z0-9_/~{}]")
_NAME_CHARACTERS = re.compile(r"[A-Za-z0-9_/]")
_SUBSTITUTION = re.compile(r"\{([^{}]*)\}")
_SUBSTITUTIONS = ("{node}", "{ns}", "{namespace}")  # what rcl expands in a topic name
MAX_NAMESPACE_LENGTH = 255 - 2 - 8  # rmw: what DDS allows, less room for the topic and prefixes
MAX_NODE_NAME_LENGTH = 255


def name_token(text: str) -> str:
    """Any text as one valid ROS name token (letters, digits, _; not starting with a digit):
    `my client!` -> `my_client_`, `0` -> `n0`."""
    token = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return token if token[:1].isalpha() else f"n{token}"


class ChannelNames:
    """The channels whose names became ROS name tokens (`{1:topic}`: `A.B` -> `A_B`, `1ARM` ->
    `n1ARM`), so that a way back (`{1:channel}`) finds the channel a token stands for: the
    channel seen with that token, else the token itself. Not for commands: a route that writes
    them reads the allow-list alone (`CommandPolicy.channel`), so no sender can take their names.

    One token, one channel: the first channel seen with a token keeps it, and another that makes
    the same token (`A-B` after `A.B`) is refused (`Held`, kind `name_collision`, naming both),
    never merged into the first one's topic. Bounded: past `limit` channels, a new one is carried
    only when its name is a token already (`IIWA_STATUS`, which no other channel can be mistaken
    for while nothing new is remembered); any other is refused (`too_many_channels`)."""

    def __init__(self, limit: int = 10_000) -> None:
        self._owner: dict[str, str] = {}  # token -> the channel that has it
        self._limit = limit
        self._lock = threading.Lock()

    def token(self, channel: str) -> str:
        """`channel`'s token, remembered; `Held` when another channel has that token already, or
        when the names are full and `channel` is no token itself."""
        token = name_token(channel)
        with self._lock:
            owner = self._owner.get(token)
            if owner is None and len(self._owner) < self._limit:
                self._owner[token] = owner = channel
        if owner == channel or (owner is None and token == channel):
            return token
        if owner is None:
            raise Held(
                "too_many_channels",
                f"{len(self._owner)} channels have ROS names already (the limit), and {channel} would be renamed "
                f"{token}: not carried",
            )
        raise Held(
            "name_collision",
            f"LCM channels {owner} and {channel} both become the ROS name {token}: {channel} is not carried "
            f"({owner}, seen first, keeps it; rename one of them)",
        )

    def channel(self, token: str) -> str:
        """The channel `token` stands for: the one that has it, else the token itself."""
        with self._lock:
            return self._owner.get(token, token)


def topic_problem(name: str) -> str | None:
    """What makes `name` no valid ROS 2 topic name (relative, absolute or private), or None."""
    if not name:
        return "it is empty"
    if name.endswith("/"):
        return "it ends with /"
    if problem := _unallowed(name, _TOPIC_CHARACTERS, "letters, digits, _, / and {} substitutions"):
        return problem
    if "~" in name[1:]:
        return "~ may only be its first character"
    # rcl wants / after a leading ~ (`~/x`); it lets one character pass (`~x`: the node's name
    # followed by x), so this does too, to refuse exactly what rclpy refuses.
    if name.startswith("~") and len(name) > 2 and name[1] != "/":
        return "~ must be followed by /"
    outside = _SUBSTITUTION.sub("", name)  # what is left once every {substitution} is taken out
    if "{" in outside or "}" in outside:
        return "it has an unmatched { or }"
    for substitution in _SUBSTITUTION.findall(name):
        if f"{{{substitution}}}" not in _SUBSTITUTIONS:
            return f"{{{substitution}}} is not a substitution ROS knows ({', '.join(_SUBSTITUTIONS)})"
    return _tokens(name)


def namespace_problem(namespace: str) -> str | None:
    """What makes `namespace` no valid node namespace ("" is the root), or None.

    A relative namespace (`sim1`) is taken as absolute (`/sim1`), as rcl does when a node is made.
    """
    if namespace in ("", "/"):
        return None
    if namespace.endswith("/"):
        return "it ends with /"
    if problem := _unallowed(namespace, _NAME_CHARACTERS, "letters, digits, _ and /"):
        return problem
    if len(namespace) > MAX_NAMESPACE_LENGTH:
        return f"it is longer than {MAX_NAMESPACE_LENGTH} characters"
    return _tokens(namespace.removeprefix("/"))


def node_name_problem(name: str) -> str | None:
    """What makes `name` no valid node name, or None."""
    if not name:
        return "it is empty"
    if problem := _unallowed(name, re.compile(r"[A-Za-z0-9_]"), "letters, digits and _"):
        return problem
    if name[0].isdigit():
        return "it starts with a digit"
    if len(name) > MAX_NODE_NAME_LENGTH:
        return f"it is longer than {MAX_NODE_NAME_LENGTH} characters"
    return None


def _unallowed(name: str, allowed: re.Pattern[str], what: str) -> str | None:
    bad = "".join(dict.fromkeys(character for character in name if not allowed.fullmatch(character)))
    return f"it has characters a ROS name cannot hold: {bad!r} (only {what})" if bad else None


def _tokens(name: str) -> str | None:
    if "//" in name:
        return "it has // (an empty part)"
    tokens = name.split("/")
    if tokens[0].startswith("~"):  # `~x` becomes the node's name followed by x: no token of its own
        tokens = tokens[1:]
    for token in tokens:
        if token[:1].isdigit():
            return f"a part of it starts with a digit: {token!r}"
    return None


# rcl's parameter names (rcl/lexer.c): name tokens separated by dots; its YAML booleans.
_PARAMETER_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
_YAML_BOOLS = {form for word in ("true", "false", "yes", "no", "on", "off")
               for form in (word, word.capitalize(), word.upper())}  # fmt: skip


def ros_argument_problem(flag: str, value: str) -> str | None:
    """What rcl would refuse in one `--ros-args` flag and value (a remap rule, a parameter), or None.

    `-r [node:]FROM:=TO`: `__ns` takes an absolute namespace, `__node` and `__name` a node name,
    anything else a topic name on either side; `-p [node:]NAME:=VALUE`: a dotted parameter name,
    and `use_sim_time` (which every node declares as a bool) a YAML bool. Other flags pass.
    """
    if flag not in ("-r", "--remap", "-p", "--param"):
        return None
    rule, separator, to = value.partition(":=")
    node, _, name = rule.rpartition(":")
    if not separator:
        return f"{value!r} is not NAME:=VALUE"
    if node and (problem := node_name_problem(node)):
        return f"{node!r} is not a valid ROS 2 node name: {problem}"
    if flag in ("-p", "--param"):
        if not _PARAMETER_NAME.fullmatch(name):
            return f"{name!r} is not a valid parameter name: letters, digits and _ in parts joined by ."
        if name == "use_sim_time" and to not in _YAML_BOOLS:
            return f"use_sim_time is a bool (true or false), not {to!r}"
        return None
    if name == "__ns":
        problem = namespace_problem(to) if to.startswith("/") else "it must be absolute (start with /)"
        return f"{to!r} is not a valid ROS 2 namespace: {problem}" if problem else None
    if name in ("__node", "__name"):
        problem = node_name_problem(to)
        return f"{to!r} is not a valid ROS 2 node name: {problem}" if problem else None
    for topic in (name, to):
        if problem := topic_problem(topic):
            return f"{topic!r} is not a valid ROS 2 topic name: {problem}"
    return None
