"""Make docs/layers.png: the package's modules on their layers, and their imports, from the code.

Run: .venv/bin/python docs/layers.py

The layers are tests/test_layers.py's table (the same one the tests hold the imports to), and
the imports are read from the source as that test reads them. Each box is one entry of the
table (a folder, or a module the table names on its own), on its layer's row; an arrow is an
import from one box to another, drawn from the importer's top edge down to the imported box's
bottom edge, so every arrow runs down or level: one running up would be a broken layer.
"""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # tests/ (the layer table and the import reader)

from tests.test_layers import GRAPH, LAYERS, holds_only_a_docstring  # noqa: E402

ROW, BOX_HEIGHT, MARGIN, WIDTH = 120, 34, 70, 2500
FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"


def room(module: str) -> str:
    """The table's entry that decides a module's layer: its box."""
    return max((name for name in LAYERS if module == name or module.startswith(name + ".")), key=len)


def label(name: str) -> str:
    short = name.removeprefix("viewer_bridge").lstrip(".").replace(".", "/")
    return short or "viewer_bridge/__init__"


def boxes(draw: ImageDraw.ImageDraw, font: ImageFont.FreeTypeFont) -> dict[str, tuple[int, int, int, int]]:
    """Each room's box, placed left to right on its layer's row (the ground floor at the bottom)."""
    by_layer: dict[int, list[str]] = defaultdict(list)
    for name in sorted({room(module) for module in GRAPH}):
        by_layer[LAYERS[name]].append(name)
    top_layer = max(by_layer)
    placed: dict[str, tuple[int, int, int, int]] = {}
    for layer, names in by_layer.items():
        y = MARGIN + (top_layer - layer) * ROW
        widths = [int(draw.textlength(label(name), font=font)) + 16 for name in names]
        gap = max(8, (WIDTH - 2 * MARGIN - sum(widths)) // (len(names) + 1))
        x = MARGIN + gap
        for name, width in zip(names, widths, strict=True):
            placed[name] = (x, y, x + width, y + BOX_HEIGHT)
            x += width + gap
    return placed


def main() -> None:
    top_layer = max(LAYERS.values())
    image = Image.new("RGB", (WIDTH, 2 * MARGIN + top_layer * ROW), "white")
    draw = ImageDraw.Draw(image)
    font = ImageFont.truetype(FONT, 15)
    placed = boxes(draw, font)
    # The packages above a module are imported with it: the root (which imports nothing until a
    # name is asked for) and each folder's `__init__.py` (a docstring, nothing else) get no arrow.
    arrows = {
        (room(module), room(name))
        for module, names in GRAPH.items()
        for name in names
        if name in GRAPH and name != "viewer_bridge" and not holds_only_a_docstring(name)
    }
    for source, target in sorted(arrows):
        if source != target:
            (x0, y0, x1, _), (u0, _, u1, v1) = placed[source], placed[target]
            colour = (200, 40, 40) if LAYERS[target] > LAYERS[source] else (150, 170, 200)
            draw.line([((x0 + x1) // 2, y0), ((u0 + u1) // 2, v1)], fill=colour, width=1)
    for layer in range(1, top_layer + 1):
        y = MARGIN + (top_layer - layer) * ROW
        draw.text((12, y + 8), str(layer), fill=(90, 90, 90), font=font)
    for name, (x0, y0, x1, y1) in placed.items():
        draw.rectangle((x0, y0, x1, y1), fill=(245, 240, 225), outline=(60, 60, 60))
        draw.text((x0 + 8, y0 + 8), label(name), fill="black", font=font)
    image.save(HERE / "layers.png", optimize=True)


if __name__ == "__main__":
    main()
