#!/usr/bin/env bash
# Installs GStreamer's RTSP server for Debian's own Python when missing: the RTSP tests
# (tests/cvs/sources/test_frame_source_rtsp.py) serve frames with it (wristmark_testing/rtsp_server.py).
# Only from the Debian archive; the project's venv does not need it.
set -euo pipefail
probe='import gi; gi.require_version("Gst", "1.0"); gi.require_version("GstRtspServer", "1.0"); from gi.repository import Gst, GstRtspServer; Gst.init(None); assert Gst.ElementFactory.find("rtpjpegpay") and Gst.ElementFactory.find("jpegparse") and Gst.ElementFactory.find("appsrc")'
if [ -x /usr/bin/python3 ] && /usr/bin/python3 -c "$probe" >/dev/null 2>&1; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi
echo "installing Debian's GStreamer RTSP server for the RTSP tests..." >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq >/dev/null
$SUDO apt-get install -y -qq --no-install-recommends python3 python3-gi gir1.2-gst-rtsp-server-1.0 \
  gstreamer1.0-plugins-base gstreamer1.0-plugins-good gstreamer1.0-plugins-bad >/dev/null
/usr/bin/python3 -c "$probe"
