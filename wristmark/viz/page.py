"""The HTML page around the Meshcat viewer: legend overlay, status line, and either a live
websocket connection (served pages) or the scene's commands inlined (self-contained snapshots).

Kept free of heavy imports (no Pinocchio): the Meshcat server process builds its page here.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Iterable, Sequence
from pathlib import Path

import meshcat

from wristmark.viz.style import LEGEND, LegendRow, css_color

MESHCAT_DIST = Path(meshcat.__file__).resolve().parent / "viewer" / "dist"  # the viewer bundle

_STYLE = """
body { margin: 0; font-family: 'DejaVu Sans', Arial, sans-serif; }
#meshcat-pane { width: 100vw; height: 100vh; overflow: hidden; }
#wm-legend { position: absolute; left: 10px; top: 10px; z-index: 10; background: rgba(255,255,255,0.82);
  border: 1px solid #bbb; border-radius: 6px; padding: 6px 10px; font-size: 12px; line-height: 1.45;
  color: #222; pointer-events: none; max-width: 290px; }
#wm-legend .wm-title { font-weight: bold; margin-bottom: 3px; }
#wm-legend .wm-sw { display: inline-block; width: 11px; height: 11px; border-radius: 6px;
  margin-right: 6px; vertical-align: -1px; border: 1px solid #555; }
#wm-status { margin-top: 4px; font-family: 'DejaVu Sans Mono', monospace; white-space: pre; font-size: 11px; }
"""

# Live pages poll the server for the latest cycle's status (JSON: an object of short strings).
_STATUS_POLL = """
(function poll() {
  fetch('/wristmark/status', {cache: 'no-store'}).then(r => r.json()).then(s => {
    const lines = Object.entries(s).map(([k, v]) => k + ': ' + v);
    document.getElementById('wm-status').textContent = lines.join('\\n');
  }).catch(() => {}).finally(() => setTimeout(poll, 250));
})();
"""

_OPEN_CONTROLS = """
try { viewer.gui.open(); viewer.animator.folder.open(); } catch (e) { console.info(e); }
"""


def legend_html(title: str, status: dict[str, str] | None = None,
                legend: Sequence[LegendRow] | None = None) -> str:
    """The legend box: title, one row per drawn item with its coloured swatches (``legend``;
    default style.LEGEND), and a status block."""
    rows_in = legend if legend is not None else tuple((label, (rgb,)) for label, rgb in LEGEND)
    rows = "".join(
        "<div>" + "".join(f'<span class="wm-sw" style="background:{css_color(rgb)}"></span>' for rgb in colors)
        + f"{html.escape(label)}</div>"
        for label, colors in rows_in
    )
    text = "\n".join(f"{k}: {v}" for k, v in (status or {}).items())
    return (f'<div id="wm-legend"><div class="wm-title">{html.escape(title)}</div>{rows}'
            f'<div id="wm-status">{html.escape(text)}</div></div>')


def served_page(title: str, open_controls: bool = False, poll_status: bool = True,
                legend: Sequence[LegendRow] | None = None) -> str:
    """Page for a Meshcat server: loads the viewer bundle from /static and connects to the
    server's websocket (same host and port); ``legend``: its rows (default style.LEGEND)."""
    script = "viewer.connect();\n"
    if open_controls:
        script += _OPEN_CONTROLS
    if poll_status:
        script += _STATUS_POLL
    return _page(title, '<script type="text/javascript" src="/static/main.min.js"></script>', script, None, legend)


def static_page(title: str, commands: Iterable[bytes], status: dict[str, str] | None = None,
                open_controls: bool = False, legend: Sequence[LegendRow] | None = None) -> str:
    """Self-contained page: the viewer bundle and every scene command inlined (base64 msgpack),
    applied synchronously on load, so the file opens from disk without any server."""
    bundle = (MESHCAT_DIST / "main.min.js").read_text(encoding="utf-8")
    blobs = json.dumps([base64.b64encode(c).decode("ascii") for c in commands])
    script = (
        f"const wmCommands = {blobs};\n"
        "for (const c of wmCommands) {\n"
        "  const s = atob(c); const b = new Uint8Array(s.length);\n"
        "  for (let i = 0; i < s.length; i++) b[i] = s.charCodeAt(i);\n"
        "  viewer.handle_command_bytearray(b);\n"
        "}\n"
        "window.wmSceneReady = true;\n"
    )
    if open_controls:
        script += _OPEN_CONTROLS
    return _page(title, f"<script>{bundle}</script>", script, status, legend)


def _page(title: str, bundle_tag: str, script: str, status: dict[str, str] | None,
          legend: Sequence[LegendRow] | None = None) -> str:
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{html.escape(title)}</title><style>{_STYLE}</style></head>
<body>
<div id="meshcat-pane"></div>
{legend_html(title, status, legend)}
{bundle_tag}
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{script}
</script>
</body>
</html>
"""
