"""The servo loop: its configuration and setup, the cycle, tip sensors, delay compensation, the play
probe, summaries and metrics, real-time helpers.
"""
