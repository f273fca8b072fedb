"""The stereo marker tracker: stereo matching, the pose solve, the marker's axis, the tracker
and its settings, results and annotated frames.
"""
