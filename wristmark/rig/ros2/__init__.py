"""ROS 2 without ROS: the messages as Cyclone DDS IDL types, the loopback-only DDS configuration
(the default), and the servo loop's bridge (``wristmark servo --ros2 [NS]``: measured_cp,
measured_js, setpoint_js out; servo_cp in). docs/ros2.md.

Everything here needs the optional ``cyclonedds`` (``pip install 'wristmark[ros2]'``) except
:mod:`rig.ros2.dds_config`, which says so in one line.
"""
