"""The user-error types every layer may raise: shown as one line, exit status 2.

It lives in ``core`` (which imports nothing of the project) so that library modules can report
bad input without importing the command line.
"""
from __future__ import annotations


class BadInput(Exception):
    """A user error reported as one line with exit status 2."""


class ConfigError(ValueError):
    """A bad run configuration; the message names the key and what is allowed."""


__all__ = ["BadInput", "ConfigError"]
