"""The wrist marker's sleeve: the coded sleeve's cells, code words and decoding, the printable sheet,
synthetic views and whether the marker is in view.
"""
