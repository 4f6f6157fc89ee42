"""Optional numba acceleration, one place for every case study.

numba is an accelerator, never a requirement: when it cannot be imported, for any reason (not
installed, or broken by another package on the path), ``jit`` returns ``None`` after one warning
and the callers use their numpy path, which gives the same results.
"""
from __future__ import annotations

import warnings
from typing import Any, Callable

SMALL_BATCH = 16
"""Up to this many scenarios, ``evaluate(..., engine="auto")`` runs the kernels' code uncompiled
(or numpy) unless numba is loaded already: the same bits, without numba's ~0.3-0.8 s import and
cache load, which costs more than a few scenarios do (start-up of ``ambiegen evaluate``)."""

_NUMBA: Any = None  # the numba module, or False once an import failed
_NUMBA_ERROR = ""  # why it failed ("ExceptionType: message")


def numba_module() -> Any:
    """numba, or False (after one RuntimeWarning) when importing it fails for any reason."""
    global _NUMBA, _NUMBA_ERROR
    if _NUMBA is None:
        try:
            import numba
        except Exception as exc:  # ImportError, or a broken dependency (AttributeError, ...)
            _NUMBA_ERROR = f"{type(exc).__name__}: {exc}"
            warnings.warn(f"numba unavailable ({_NUMBA_ERROR}); using the numpy paths", RuntimeWarning, stacklevel=2)
            _NUMBA = False
        else:
            _NUMBA = numba
    return _NUMBA


def jit(func: Callable) -> Callable | None:
    """``func`` compiled by numba (cached on disk, IEEE floating point, no Python exceptions), or None."""
    numba = numba_module()
    if not numba:
        return None
    return numba.njit(cache=True, error_model="numpy")(func)


COMPILED: dict[Callable, Callable] = {}
"""What ``compiled_or_plain`` gave each function (a test sets a function's entry to the function
itself to run its plain path)."""


def compiled_or_plain(func: Callable) -> Callable:
    """``func`` compiled by numba on first use, once per process, else ``func`` itself (the same bits)."""
    got = COMPILED.get(func)
    if got is None:
        got = COMPILED[func] = jit(func) or func
    return got


def numba_error() -> str:
    """Why numba does not load ('' when it does); tries the import once."""
    numba_module()
    return _NUMBA_ERROR
