"""The simulated endoscope's renderer: the arm ray caster, background, optics, sensor, settings,
the rendering process and the rendered frame source.
"""
