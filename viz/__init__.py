"""Meshcat scene and plots."""
