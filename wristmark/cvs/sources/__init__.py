"""Stereo frame sources: image folders, video files, V4L2 and network cameras (MJPEG, RTSP), ROS 2 bags,
the newest-frame semantics of live sources, and the MJPEG server that serves frames.
"""
