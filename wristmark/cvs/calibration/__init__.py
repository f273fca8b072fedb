"""Stereo calibration: boards, the calibration itself, the calibration file formats it reads and
writes (wristmark YAML, OpenCV, ROS camera_info, Kalibr), checks and reports, registration files.
"""
