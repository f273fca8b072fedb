"""Self-contained static HTML of a Meshcat scene, written without any server.

:class:`RecordingWindow` stands in for Meshcat's ZMQ window: every command a
``meshcat.Visualizer`` sends is applied to a scene tree in memory (the server's rules, see
viz.command_tree), and :meth:`RecordingWindow.html` inlines the viewer bundle and the tree's
commands into one page that opens from a file (animations and their time slider included).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import meshcat

from wristmark.models.errors import InputError
from wristmark.viz import command_tree
from wristmark.viz.page import static_page
from wristmark.viz.style import LegendRow


class RecordingWindow:
    """A Meshcat window that records the scene instead of sending it anywhere."""

    web_url = "(static snapshot)"

    def __init__(self) -> None:
        self.tree = command_tree.new_tree()
        self.count = 0

    def send(self, command: Any) -> None:
        """Apply one meshcat.commands object to the recorded scene."""
        kind, path, data = command_tree.pack(command)
        self.tree, _ = command_tree.apply(self.tree, kind, path, data)
        self.count += 1

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """Same API as viz.viewer_client.ZmqWindow.batch (nothing to group here)."""
        yield

    def commands(self) -> list[bytes]:
        """The packed commands that rebuild the recorded scene, in order."""
        return list(command_tree.replay(self.tree))

    def get_scene(self) -> str:
        """Static HTML, as ``meshcat.Visualizer.static_html()`` expects of a window."""
        return self.html("wristmark")

    def html(self, title: str, status: dict[str, str] | None = None, open_controls: bool = False,
             legend: Sequence[LegendRow] | None = None) -> str:
        """The self-contained page: legend (``legend``'s rows; default style.LEGEND), ``status``
        lines, the scene (and its animation)."""
        return static_page(title, self.commands(), status, open_controls, legend)


def recording_visualizer() -> tuple[meshcat.Visualizer, RecordingWindow]:
    """A Meshcat visualizer that records into a :class:`RecordingWindow`."""
    window = RecordingWindow()
    return meshcat.Visualizer(window=window), window


def write_html(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` (parent folders created); one-line InputError on failure."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")
    except OSError as e:
        raise InputError(f"cannot write {p}: {e.strerror or e}") from e
    return p
