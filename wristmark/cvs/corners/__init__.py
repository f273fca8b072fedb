"""The paper's X-corner detector (Sec. III.A): corner likelihood, sub-pixel refinement, the X-corner
test, the marker chain, saddle-point fallback, planar chessboards.
"""
