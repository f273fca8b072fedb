"""What a run leaves behind: run logs, output folders, ROS 2 bags, tracked sequences.
"""
