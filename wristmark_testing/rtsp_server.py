"""A real RTSP server for the tests: a folder of JPEG frames served as RTP/JPEG (RFC 2435).

Run with Debian's own Python, which has GStreamer's RTSP server (scripts/ensure-rtsp-server.sh
installs it; the project's venv does not need it):

    /usr/bin/python3 wristmark_testing/rtsp_server.py DIR FPS [--once]

DIR holds ``frame_00000.jpg``, ``frame_00001.jpg``, ... (at most 2040 px wide and high: the
RTP/JPEG payload's limit). The server binds 127.0.0.1 on a port the OS picks and prints one
line, ``rtsp://127.0.0.1:PORT/stereo``, once it listens; then it serves the frames at FPS in a
loop (``--once``: the frames once, then the stream ends) until it is terminated.
It imports nothing of wristmark: it runs outside the project's venv.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

import gi

gi.require_version("Gst", "1.0")
gi.require_version("GstRtspServer", "1.0")
from gi.repository import GLib, Gst, GstRtspServer  # noqa: E402


def frames_of(folder: Path) -> list[bytes]:
    """The folder's JPEG frames, in order."""
    files = sorted(folder.glob("frame_*.jpg"))
    if not files:
        raise SystemExit(f"error: no frame_*.jpg in {folder}")
    return [f.read_bytes() for f in files]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("fps", type=int)
    ap.add_argument("--once", action="store_true", help="serve the frames once, then end the stream")
    args = ap.parse_args()
    frames = frames_of(args.folder)
    Gst.init(None)
    server = GstRtspServer.RTSPServer()
    server.set_address("127.0.0.1")
    server.set_service("0")  # the OS picks the port
    factory = GstRtspServer.RTSPMediaFactory()
    factory.set_launch("( appsrc name=src is-live=true do-timestamp=true format=time "
                       f'caps="image/jpeg,framerate={args.fps}/1" ! jpegparse ! rtpjpegpay name=pay0 pt=26 )')
    factory.set_shared(True)

    def configure(_factory: object, media: GstRtspServer.RTSPMedia) -> None:
        src = media.get_element().get_by_name("src")
        state = {"k": 0}

        def push() -> bool:  # one frame per period, on the wall clock (a live camera's pace)
            k = state["k"]
            if args.once and k >= len(frames):
                src.emit("end-of-stream")
                return False
            state["k"] = k + 1
            return src.emit("push-buffer", Gst.Buffer.new_wrapped(frames[k % len(frames)])) == Gst.FlowReturn.OK

        GLib.timeout_add(max(1, round(1000 / args.fps)), push)

    factory.connect("media-configure", configure)
    server.get_mount_points().add_factory("/stereo", factory)
    if server.attach(None) == 0:
        print("error: cannot listen on 127.0.0.1", file=sys.stderr)
        return 1
    print(f"rtsp://127.0.0.1:{server.get_bound_port()}/stereo", flush=True)
    main_loop = GLib.MainLoop()
    signal.signal(signal.SIGTERM, lambda *_: main_loop.quit())
    main_loop.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
