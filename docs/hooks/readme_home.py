"""MkDocs hook: the site's home page is README.md, with its links into docs/ made relative to the site.

README.md is the front door on GitHub and in the clone, where its links say `docs/ros2.md`; in the
site, whose pages are docs/ itself, the same page is `index.md` and the link is `ros2.md`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

README = Path(__file__).resolve().parents[2] / "README.md"


def on_page_read_source(page: Any, config: Any) -> str | None:
    if page.file.src_uri != "index.md":
        return None
    return re.sub(r"\]\(docs/", "](", README.read_text())
