"""The servo loop, actuator protocol/driver/emulator, experiments and the command line."""
