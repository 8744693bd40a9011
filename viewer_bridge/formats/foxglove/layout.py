"""A Foxglove layout for the bridge's topics (the app's Layouts > Import from file), built with
foxglove-sdk's `foxglove.layouts`, whose serialisation is the app's own layout JSON.

What the layout holds: a 3D panel on the scene topics (`foxglove.SceneUpdate`) displayed in the
world frame, its transform topics named beside them; an Image panel per camera image topic; a
Plot panel of numeric fields (message paths, `numeric_paths` picks them from a message). The
playback bar is no part of a layout: the app shows it for any data source with a timeline, as
`viewer-bridge play`'s server is.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import cast

import foxglove.layouts as fl

PLOT_FIELDS_PER_TOPIC = 3  # the first few numbers of each message: a start the user edits
PLOT_FIELDS = 12  # in all: a plot of more lines is read by no one


@dataclass(frozen=True)
class LayoutTopics:
    """The topics a layout shows: scenes (the ones hidden at first among them), transforms, camera
    images, message paths to plot, and the frame the 3D panel displays."""

    scenes: tuple[str, ...] = ()
    hidden_scenes: frozenset[str] = frozenset()  # listed in the 3D panel, off until the user turns them on
    transforms: tuple[str, ...] = ()
    images: tuple[str, ...] = ()
    plots: tuple[str, ...] = ()
    frame: str = "world"


def foxglove_layout(topics: LayoutTopics) -> fl.Layout:
    """The 3D panel (wide) beside a column of the image panels, the plot under both."""
    top: fl.Content = _three_d(topics)
    if topics.images:
        images = [fl.SplitItem(content=_image(topic)) for topic in topics.images]
        column = fl.SplitContainer(direction="column", items=images)
        top = fl.SplitContainer(
            direction="row", items=[fl.SplitItem(proportion=2, content=top), fl.SplitItem(content=column)]
        )
    series = [fl.PlotSeries(value=path) for path in topics.plots]
    plot = fl.PlotPanel(title="LCM fields", config=fl.PlotConfig(paths=series))
    return fl.Layout(
        content=fl.SplitContainer(
            direction="column",
            items=[fl.SplitItem(proportion=3, content=top), fl.SplitItem(proportion=1, content=plot)],
        )
    )


def _three_d(topics: LayoutTopics) -> fl.ThreeDeePanel:
    shown: dict[str, fl.BaseRendererTopicSettings] = {
        topic: fl.BaseRendererSceneUpdateTopicSettings(visible=topic not in topics.hidden_scenes)
        for topic in topics.scenes
    }
    # The 3D panel reads every transform topic whatever its settings say, and the layouts module
    # has no settings class of a FrameTransforms topic: named with the settings all topics share.
    for topic in topics.transforms:
        shown[topic] = cast(fl.BaseRendererTopicSettings, fl.BaseRendererBaseSettings(visible=True))
    config = fl.ThreeDeeConfig(follow_tf=topics.frame, fixed_frame=topics.frame, topics=shown)
    return fl.ThreeDeePanel(title="Drake scene", config=config)


def _image(topic: str) -> fl.ImagePanel:
    return fl.ImagePanel(title=topic, config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=topic)))


def numeric_paths(message: object) -> list[str]:
    """The message's numbers worth a first plot, as message-path suffixes (`.joint_position[0]`):
    floating-point fields before integer ones (counts and times), each array by its first element,
    at most `PLOT_FIELDS_PER_TOPIC`. `message`: a decoded message as JSON (dicts, lists, numbers)."""
    leaves = list(_numbers(message, ""))
    floats = [path for path, is_float in leaves if is_float]
    integers = [path for path, is_float in leaves if not is_float]
    return (floats + integers)[:PLOT_FIELDS_PER_TOPIC]


def _numbers(value: object, path: str) -> Iterator[tuple[str, bool]]:
    """(path, whether a float) of every number in `value`, in field order; an array's first element only."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return
    if isinstance(value, int | float):
        yield path, isinstance(value, float)
    elif isinstance(value, dict):
        for key, field in value.items():
            yield from _numbers(field, f"{path}.{key}")
    elif isinstance(value, list) and value:
        yield from _numbers(value[0], f"{path}[0]")


_PLAIN_TOPIC = re.compile(r"[A-Za-z0-9_/]+")


def message_path(topic: str, field: str) -> str:
    """A message path of `topic` and a field path (`.a[0]`): a topic of other characters quoted."""
    if _PLAIN_TOPIC.fullmatch(topic):
        return topic + field
    return '"' + topic.replace("\\", "\\\\").replace('"', '\\"') + '"' + field
