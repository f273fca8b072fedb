"""Independent checkers for wristmark's tests and benchmarks, written only from docs/design.md.

Nothing here imports ``wristmark`` and ``wristmark`` never imports this package
(tests/project/test_layers.py checks both), so a check here cannot share a mistake with the code it checks:
``reference_chain`` (the kinematic chain on 4x4 matrices), ``independent_render`` (a second
stereo renderer of the marker, numpy/OpenCV only), ``independent_dataset_check`` (every rule
of the stereo dataset format), and ``x_corner`` (an X-corner drawn at a sub-pixel position for
the corner fits' tests). A separate top-level package of the same distribution (like
``numpy.testing``, but outside the library) so that tests and ``bench/`` import it without
``sys.path`` edits.
"""
