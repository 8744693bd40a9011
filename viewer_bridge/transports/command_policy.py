"""Which LCM channels the way back may write, and how old a command may be when it is sent.

The generic way back (`ros_to_lcm`: ROS 2 over DDS or Zenoh, and Foxglove clients, publishing on
`/lcm_in/<channel>`) writes into LCM buses that drive real arms and grippers. So it writes no
channel the user has not named: `commands.allow` in a config, or `--allow-commands REGEX` on
`viewer-bridge run`, each a regular expression matched against the whole channel name. With none
named, nothing is written, and each refused message is counted (`not_allowed`) and answered.

A command is worth sending only while it is fresh: a message older than `max_age_ms` when it
would be sent (measured from the bridge's own receive time) is dropped and counted (`stale`),
never replayed after a stall. The senders' own stamps (a ROS 2 `header.stamp`, an LCM `utime`)
are not used: they come from another clock (a simulation's, another host's) that the bridge
cannot compare with its own.

The allow-list is also the table of names: `/lcm_in/<name>` commands the channel `<name>` when
the allow-list allows it, else the channel the allow-list names literally whose ROS name token
`<name>` is (`IIWA-COMMAND`, named so, for `/lcm_in/IIWA_COMMAND`), else nothing. What arrives on
LCM never changes it, so no sender on the bus can take a command's name (`channel`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TypeVar

from pydantic import BaseModel, ConfigDict, Field, field_validator

from viewer_bridge.errors import InvalidSetting
from viewer_bridge.transports.ros_names import name_token

COMMAND_FLAG = "--allow-commands"
DEFAULT_MAX_AGE_MS = 200.0


Patterns = TypeVar("Patterns", bound=Sequence[str])
_REGEX_SYNTAX = frozenset(".^$*+?{}[]()")  # unescaped, any of these makes a pattern no plain name


def literal_channels(pattern: str) -> list[str]:
    """The channels `pattern` names literally: its `|`-separated alternatives made only of plain
    characters and escaped punctuation (`IIWA-COMMAND|WSG\\.COMMAND` -> `IIWA-COMMAND`,
    `WSG.COMMAND`); none when it holds any other regex syntax (`IIWA_.*`, `(A|B)`, `\\d`)."""
    channels, current, escaped = [], [], False
    for character in pattern:
        if escaped:
            if character.isalnum():  # \d, \A, \n: classes, anchors and escapes, no plain character
                return []
            current.append(character)
            escaped = False
        elif character == "\\":
            escaped = True
        elif character == "|":
            channels.append("".join(current))
            current = []
        elif character in _REGEX_SYNTAX:
            return []
        else:
            current.append(character)
    channels.append("".join(current))
    return [] if escaped else [channel for channel in channels if channel]


def regular_expressions(patterns: Patterns) -> Patterns:
    """`patterns`, each checked to compile: an `InvalidSetting` (a ValueError) naming the first that
    does not (a config's validators turn it into a ConfigError with its line)."""
    for pattern in patterns:
        try:
            re.compile(pattern)
        except re.error as error:
            raise InvalidSetting(f"{pattern!r} is not a regular expression: {error}") from None
    return patterns


def alternatives(pattern: str) -> list[str]:
    """The top-level alternatives of a regex (`a|(b|c)|[|]` -> `a`, `(b|c)`, `[|]`), each
    without a leading `^` (a full match anchors anyway)."""
    parts, depth, start, index, in_class = [], 0, 0, 0, False
    while index < len(pattern):
        char = pattern[index]
        if char == "\\":
            index += 1  # the escaped character is no operator
        elif in_class:
            in_class = char != "]" or pattern[index - 1] == "["
        elif char == "[":
            in_class = True
        elif char == "(":
            depth += 1
        elif char == ")":
            depth -= 1
        elif char == "|" and depth == 0:
            parts.append(pattern[start:index])
            start = index + 1
        index += 1
    parts.append(pattern[start:])
    return [part.removeprefix("^") for part in parts]


def topic_pattern_problem(pattern: str) -> str | None:
    """Why a ROS 2 topic regex (`--ros-topics`, `ros_topics:`) can never match a topic, or None:
    an alternative that begins with a name's character, where every ROS 2 topic begins with `/`."""
    for part in alternatives(pattern):
        if re.match(r"[A-Za-z0-9_~]", part):
            meant = "/" + part.removeprefix("~")
            return f"{part!r} can never match a ROS 2 topic (every topic name starts with /): did you mean {meant!r}?"
    return None


def channel_pattern_problem(pattern: str) -> str | None:
    """Why an LCM channel regex (`--allow-commands`, `commands.allow`) can never match a channel a
    command can reach, or None: an alternative that begins with `/`, a ROS 2 topic's way of
    naming (the way back's topic `/lcm_in/<channel>` names the channel after `/lcm_in/`)."""
    for part in alternatives(pattern):
        if part.startswith("/"):
            channel = part.removeprefix("/lcm_in/").lstrip("/")
            return (
                f"{part!r} can never match an LCM channel (a channel is named without a leading /): "
                f"did you mean {channel!r}?"
            )
    return None


def checked(patterns: Patterns, problem: Callable[[str], str | None]) -> Patterns:
    """`patterns`, each a regular expression with no `problem`: an `InvalidSetting` (a ValueError)
    naming the first that has one (a config's validators turn it into a ConfigError with its line)."""
    for pattern in regular_expressions(patterns):
        if (found := problem(pattern)) is not None:
            raise InvalidSetting(found)
    return patterns


class CommandPolicy(BaseModel):
    """A config's `commands:` section."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # Regular expressions, each matched against the whole LCM channel name (`IIWA_COMMAND|WSG_COMMAND`).
    allow: tuple[str, ...] = ()
    # A command older than this when it would be sent is dropped (`stale`); a route's own
    # `max_age_ms` overrides it.
    max_age_ms: float = Field(DEFAULT_MAX_AGE_MS, gt=0)

    @field_validator("allow")
    @classmethod
    def _regular_expressions(cls, allow: tuple[str, ...]) -> tuple[str, ...]:
        return checked(allow, channel_pattern_problem)

    @cached_property
    def _allowed(self) -> tuple[re.Pattern[str], ...]:
        """The patterns, compiled once."""
        return tuple(re.compile(pattern) for pattern in self.allow)

    def allows(self, channel: str) -> bool:
        """Whether the way back may write LCM `channel`."""
        return any(pattern.fullmatch(channel) for pattern in self._allowed)

    @cached_property
    def _named(self) -> dict[str, str]:
        """ROS name token -> the channel the allow-list names literally that has it (the first)."""
        named: dict[str, str] = {}
        for pattern in self.allow:
            for channel in literal_channels(pattern):
                named.setdefault(name_token(channel), channel)
        return named

    def channel(self, name: str) -> str:
        """The LCM channel a command on `/lcm_in/<name>` goes to: `name` when allowed, else the
        channel the allow-list names literally whose ROS name token `name` is, else `name` (then
        refused as not allowed). Only the allow-list decides: no channel seen on a bus does."""
        return name if self.allows(name) else self._named.get(name, name)

    def collisions(self) -> list[str]:
        """Each pair of allowed channels that would take one ROS name, and which one has it: said
        at start, for the one left out can be commanded by no `/lcm_in` name."""
        said = []
        for pattern in self.allow:
            for channel in literal_channels(pattern):
                name = name_token(channel)
                if channel != (keeper := self.channel(name)):
                    said.append(
                        f"allowed LCM channels {keeper} and {channel} would both be commanded as "
                        f"/lcm_in/{name}: it commands {keeper}; {channel} cannot be commanded (rename one)"
                    )
        return said

    def widened(self, patterns: list[str]) -> CommandPolicy:
        """This policy with more channels allowed (`--allow-commands` on top of the config's)."""
        return CommandPolicy(allow=(*self.allow, *patterns), max_age_ms=self.max_age_ms)

    def describe(self) -> str:
        """What may be commanded, for the start-up line."""
        return ", ".join(self.allow) if self.allow else "none"

    def refusal(self, channel: str) -> str:
        """Why a message for `channel` is not written, and how to allow it."""
        named = f" (allowed: {', '.join(self.allow)})" if self.allow else " (none is allowed)"
        return (
            f"LCM channel {channel} may not be commanded{named}: run with {COMMAND_FLAG} "
            f"'{re.escape(channel)}', or name it in the config's commands: {{allow: [...]}}"
        )
