"""Scenarios: the user-facing form (JSON, dicts) and the genome form (numeric matrices).

A scenario is an ordered list of at most ``m_max`` environment elements, each with the same
attributes. Users and files see ``{"problem": "robot", "elements": [{"type": "horizontal", ...}]}``;
the search sees a *genome*: a flat float row ``[m, e0a0, e0a1, ..., e(m_max-1)a(n-1)]`` whose unused
cells are 0, so a population is one ``(P, 1 + m_max * n)`` array that pymoo can carry and numpy can
process at once. ``GenomeCodec`` converts between the two and between rows and
``(P, m_max, n)`` matrices plus lengths.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .attributes import Attribute, ScenarioError


@dataclass
class Scenario:
    """An ordered list of elements (dicts attribute name -> value) for one problem."""

    problem: str
    elements: list[dict[str, Any]]
    metadata: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"problem": self.problem, "elements": [dict(e) for e in self.elements]}
        if self.metadata:
            out["metadata"] = self.metadata
        return out

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent, sort_keys=False)

    @staticmethod
    def parse_json(text: str) -> dict[str, Any]:
        """Parse JSON text into a dict, turning syntax errors into ``ScenarioError``."""
        try:
            data = json.loads(text, parse_constant=_Constant)
        except json.JSONDecodeError as exc:
            raise ScenarioError("json", f"malformed JSON at line {exc.lineno} column {exc.colno}: {exc.msg}")
        bad = first_non_finite(data)
        if bad is not None:  # named like every other field error (elements[2].temperature), not just "json"
            where, value = bad
            text_value = value.name if isinstance(value, _Constant) else repr(value)
            raise ScenarioError(where or "json", f"{text_value} is not a finite number", "finite numbers")
        if not isinstance(data, dict):
            raise ScenarioError("json", "the top level must be an object", '{"problem": ..., "elements": [...]}')
        return data


class _Constant:
    """NaN / Infinity / -Infinity as written in the JSON text, kept until its field is known."""

    def __init__(self, name: str):
        self.name = name


def first_non_finite(value: Any, where: str = "") -> tuple[str, Any] | None:
    """The path (``elements[2].temperature``) and value of the first NaN/infinite number, or None.

    Finds JSON's NaN/Infinity constants and overflowing literals such as ``1e999`` alike.
    """
    if isinstance(value, _Constant) or (isinstance(value, float) and not math.isfinite(value)):
        return where, value
    if isinstance(value, dict):
        for key, item in value.items():
            found = first_non_finite(item, f"{where}.{key}" if where else str(key))
            if found:
                return found
    if isinstance(value, list):
        for index, item in enumerate(value):
            found = first_non_finite(item, f"{where or 'json'}[{index}]")
            if found:
                return found
    return None


class GenomeCodec:
    """Converts scenarios <-> genome rows <-> (matrix, length) batches for one attribute list."""

    def __init__(self, problem: str, attributes: Sequence[Attribute], m_min: int, m_max: int):
        self.problem = problem
        self.attributes = tuple(attributes)
        self.names = tuple(a.name for a in self.attributes)
        self.m_min = m_min
        self.m_max = m_max
        self.n_attr = len(self.attributes)
        self.n_var = 1 + m_max * self.n_attr

    # --- batches -------------------------------------------------------------------------
    def split(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``(P, n_var)`` -> matrices ``(P, m_max, n_attr)`` and lengths ``(P,)``."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        lengths = np.rint(X[:, 0]).astype(int)
        G = X[:, 1:].reshape(len(X), self.m_max, self.n_attr)
        return G, lengths

    def join(self, G: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        """Matrices and lengths -> canonical rows (cells past the length set to 0)."""
        G = np.asarray(G, dtype=float).reshape(-1, self.m_max, self.n_attr).copy()
        lengths = np.asarray(lengths, dtype=int).reshape(-1)
        G[np.arange(self.m_max)[None, :] >= lengths[:, None]] = 0.0
        return np.concatenate([lengths[:, None].astype(float), G.reshape(len(G), -1)], axis=1)

    def canonical(self, X: np.ndarray) -> np.ndarray:
        return self.join(*self.split(X))

    def in_domain(self, G: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        """True where every used cell is inside its attribute's domain and the length is legal."""
        ok = (lengths >= self.m_min) & (lengths <= self.m_max)
        used = np.arange(self.m_max)[None, :] < lengths[:, None]
        for j, attr in enumerate(self.attributes):
            ok &= np.all(attr.in_domain(G[:, :, j]) | ~used, axis=1)
        return ok

    def domain_reason(self, cells: np.ndarray, length: int) -> str:
        """Why one genome (``(m_max, n_attr)`` cells) fails ``in_domain``, naming the first bad cell."""
        if not self.m_min <= length <= self.m_max:
            return f"domain: {length} elements (allowed {self.m_min}..{self.m_max})"
        for i in range(length):
            for j, attr in enumerate(self.attributes):
                if not attr.in_domain(cells[i, j]):
                    return f"domain: elements[{i}].{attr.name} = {cells[i, j]:g} ({attr.describe()})"
        return "domain: cell outside its domain"

    # --- single scenarios ----------------------------------------------------------------
    def to_row(self, scenario: Scenario) -> np.ndarray:
        G = np.zeros((self.m_max, self.n_attr))
        for i, element in enumerate(scenario.elements):
            for j, attr in enumerate(self.attributes):
                G[i, j] = attr.encode(element[attr.name], f"elements[{i}].{attr.name}")
        return self.join(G[None], np.array([len(scenario.elements)]))[0]

    def from_row(self, row: np.ndarray, metadata: dict | None = None) -> Scenario:
        G, lengths = self.split(row)
        elements = [
            {attr.name: attr.decode(G[0, i, j]) for j, attr in enumerate(self.attributes)}
            for i in range(lengths[0])
        ]
        return Scenario(self.problem, elements, dict(metadata or {}))

    def from_rows(self, X: np.ndarray) -> list[Scenario]:
        return [self.from_row(row) for row in np.atleast_2d(X)]

    def validate(self, data: dict[str, Any]) -> Scenario:
        """Check a parsed JSON dict field by field; raise ``ScenarioError`` naming the first bad one.

        Never repairs: a value outside its domain is an error, not a clipped value.
        """
        if not isinstance(data, dict):
            raise ScenarioError("scenario", "must be an object", '{"problem": ..., "elements": [...]}')
        unknown = set(data) - {"problem", "elements", "metadata"}
        if unknown:
            raise ScenarioError(sorted(unknown)[0], "unknown top-level field", "problem, elements, metadata")
        if data.get("problem") != self.problem:
            raise ScenarioError("problem", f"expected {self.problem!r}, got {data.get('problem')!r}")
        elements = data.get("elements")
        if not isinstance(elements, list):
            raise ScenarioError("elements", "missing or not a list", f"a list of {self.m_min}..{self.m_max} objects")
        if not self.m_min <= len(elements) <= self.m_max:
            raise ScenarioError(
                "elements", f"{len(elements)} elements", f"{self.m_min}..{self.m_max} elements"
            )
        metadata = data.get("metadata") or {}
        if not isinstance(metadata, dict):
            raise ScenarioError("metadata", "must be an object")
        clean = []
        for i, element in enumerate(elements):
            where = f"elements[{i}]"
            if not isinstance(element, dict):
                raise ScenarioError(where, "must be an object", ", ".join(self.names))
            extra = set(element) - set(self.names)
            if extra:
                raise ScenarioError(f"{where}.{sorted(extra)[0]}", "unknown attribute", ", ".join(self.names))
            values = {}
            for attr in self.attributes:
                if attr.name not in element:
                    raise ScenarioError(f"{where}.{attr.name}", "missing attribute", attr.describe())
                code = attr.encode(element[attr.name], f"{where}.{attr.name}")
                values[attr.name] = attr.decode(code)
            clean.append(values)
        return Scenario(self.problem, clean, metadata)


def is_finite_json(value: Any) -> bool:
    """True if a (nested) JSON value holds no NaN/inf floats."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(is_finite_json(v) for v in value.values())
    if isinstance(value, list):
        return all(is_finite_json(v) for v in value)
    return True
