"""What the tip is asked to do: trajectories (the paper's cube, accuracy targets) and orientation.
"""
