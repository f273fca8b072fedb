"""The wire to the actuator box: protocol v1 / v2 (COBS framing, CRC-16), the host driver and the
servo loop's links (serial, direct).
"""
