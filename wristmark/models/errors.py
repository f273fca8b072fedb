"""The one exception hierarchy of wristmark: every documented failure is a ``WristmarkError``."""

from __future__ import annotations


class WristmarkError(Exception):
    """Base of every error wristmark raises on purpose; its message is one line naming the fix."""


class ConfigError(WristmarkError, ValueError):
    """A configuration file or value is malformed (message names the key and the file)."""


class LimitError(WristmarkError, ValueError):
    """A configuration or command lies outside the joint / actuator limits."""


class InputError(WristmarkError, ValueError):
    """Bad user input that is not a configuration: images, paths, arrays with NaNs."""
