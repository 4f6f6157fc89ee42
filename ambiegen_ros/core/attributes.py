"""Attribute specifications: the rows of a scenario matrix.

Every attribute maps its user-facing values to a numeric *code* so that a whole population can be
stored as one float array and processed with numpy:

* ``Categorical``: code = index into ``values`` (0, 1, ...);
* ``IntRange``: code = the integer value itself (``low, low + step, ..., high``);
* ``FloatInterval``: code = the value itself (closed interval).

``tolerance`` is used by the Jaccard diversity: two codes are "the same" when they are equal
(categorical) or differ by at most ``tolerance`` (numeric).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Union

import numpy as np


class ScenarioError(ValueError):
    """A scenario (or one of its fields) breaks the problem's format or domains.

    ``field`` names the offending place (e.g. ``elements[3].size``) and ``allowed`` says what would
    have been accepted, so that CLIs and sim nodes can report it without a traceback.
    """

    def __init__(self, field: str, message: str, allowed: str | None = None):
        self.field = field
        self.message = message
        self.allowed = allowed
        text = f"{field}: {message}"
        if allowed:
            text += f" (allowed: {allowed})"
        super().__init__(text)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


@dataclass(frozen=True)
class Categorical:
    """A set of named realisations; compared by equality."""

    name: str
    values: tuple
    unit: str = ""

    tolerance = 0.0

    @property
    def low(self) -> float:
        return 0.0

    @property
    def high(self) -> float:
        return float(len(self.values) - 1)

    def describe(self) -> str:
        return "|".join(str(v) for v in self.values)

    def encode(self, value: Any, field: str) -> float:
        if isinstance(value, bool) or value not in self.values:
            raise ScenarioError(field, f"unknown value {value!r}", self.describe())
        # `value in values` is True for 1 == 1.0; keep the exact type of the declared value.
        for index, declared in enumerate(self.values):
            if type(declared) is type(value) and declared == value:
                return float(index)
        raise ScenarioError(field, f"wrong type {type(value).__name__} for {value!r}", self.describe())

    def decode(self, code: float) -> Any:
        return self.values[int(round(code))]

    def sample(self, rng: np.random.Generator, size) -> np.ndarray:
        return rng.integers(0, len(self.values), size=size).astype(float)

    def in_domain(self, codes: np.ndarray) -> np.ndarray:
        codes = np.asarray(codes, dtype=float)
        return (codes >= 0) & (codes <= self.high) & (codes == np.round(codes))

    def same(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.asarray(a) == np.asarray(b)


@dataclass(frozen=True)
class IntRange:
    """Integers ``low, low + step, ..., high`` (inclusive)."""

    name: str
    low: int
    high: int
    step: int = 1
    tolerance: float = 0.0
    unit: str = ""

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"integers {self.low}..{self.high} step {self.step}{unit}"

    @property
    def n_values(self) -> int:
        return (self.high - self.low) // self.step + 1

    def encode(self, value: Any, field: str) -> float:
        if not _is_number(value):
            raise ScenarioError(field, f"expected an integer, got {value!r}", self.describe())
        if isinstance(value, (float, np.floating)):
            if not math.isfinite(value):
                raise ScenarioError(field, f"not a finite number: {value!r}", self.describe())
            if value != int(value):
                raise ScenarioError(field, f"expected an integer, got {value!r}", self.describe())
        ivalue = int(value)
        if ivalue < self.low or ivalue > self.high or (ivalue - self.low) % self.step:
            raise ScenarioError(field, f"value {value!r} outside the domain", self.describe())
        return float(ivalue)

    def decode(self, code: float) -> int:
        return int(round(code))

    def sample(self, rng: np.random.Generator, size) -> np.ndarray:
        return (self.low + self.step * rng.integers(0, self.n_values, size=size)).astype(float)

    def in_domain(self, codes: np.ndarray) -> np.ndarray:
        codes = np.asarray(codes, dtype=float)
        offset = codes - self.low
        return (codes >= self.low) & (codes <= self.high) & (np.mod(offset, self.step) == 0)

    def same(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.abs(np.asarray(a, dtype=float) - np.asarray(b, dtype=float)) <= self.tolerance


@dataclass(frozen=True)
class FloatInterval:
    """A closed real interval ``[low, high]``."""

    name: str
    low: float
    high: float
    tolerance: float = 0.0
    unit: str = ""

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"numbers in [{self.low}, {self.high}]{unit}"

    def encode(self, value: Any, field: str) -> float:
        if not _is_number(value):
            raise ScenarioError(field, f"expected a number, got {value!r}", self.describe())
        fvalue = float(value)
        if not math.isfinite(fvalue):
            raise ScenarioError(field, f"not a finite number: {value!r}", self.describe())
        if fvalue < self.low or fvalue > self.high:
            raise ScenarioError(field, f"value {value!r} outside the domain", self.describe())
        return fvalue

    def decode(self, code: float) -> float:
        return float(code)

    def sample(self, rng: np.random.Generator, size) -> np.ndarray:
        return rng.uniform(self.low, self.high, size=size)

    def in_domain(self, codes: np.ndarray) -> np.ndarray:
        codes = np.asarray(codes, dtype=float)
        return np.isfinite(codes) & (codes >= self.low) & (codes <= self.high)

    def same(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.abs(np.asarray(a, dtype=float) - np.asarray(b, dtype=float)) <= self.tolerance


Attribute = Union[Categorical, IntRange, FloatInterval]
