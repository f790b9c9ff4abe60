"""Disallowed combinations and linear constraints: boolean expressions over factor names, read with
Python's `ast` (a whitelist of node types, never evaluated) and compiled to postfix programs that
the exchange kernel runs on every trial point.

    disallowed = ["Direction == 'Crossing' and Pedestrians == 6"]   # no run may satisfy one
    constraints = ["Speed + 0.5 * Density <= 1.5"]                    # every run must satisfy each

Numeric factors are compared in their own units; a categorical factor only with == and != or
`in` against its level names.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError
from designs.factors import CategoricalFactor, DesignFactor

#: How the compiled kernels read a factor's setting: a coded number, or a level index.
NUMERIC, CATEGORICAL = 0, 1
#: Opcodes of a program (postfix); `designs/kernels.py` (`disallowed`) runs them.
VAR, CONST, ADD, SUB, MUL, DIV, NEG, LT, LE, GT, GE, EQ, NE, AND, OR, NOT = range(16)
_COMPARE = {ast.Eq: EQ, ast.NotEq: NE, ast.Lt: LT, ast.LtE: LE, ast.Gt: GT, ast.GtE: GE}
_ARITHMETIC = {ast.Add: ADD, ast.Sub: SUB, ast.Mult: MUL, ast.Div: DIV}
#: Longest expression accepted, in characters.
MAX_LENGTH = 500


@dataclass(frozen=True)
class Restrictions:
    """The spec's expressions and the programs that say whether a point is disallowed."""

    disallowed: tuple[str, ...]
    constraints: tuple[str, ...]
    ops: np.ndarray
    args: np.ndarray
    bounds: np.ndarray

    def __bool__(self) -> bool:
        return len(self.bounds) > 1

    def allowed(self, points: np.ndarray, factors: tuple[DesignFactor, ...]) -> np.ndarray:
        """(N,) whether each (N, k) point of settings is allowed."""
        from designs.kernels import disallowed  # numba loads only when points are checked

        centre, half, kinds = factor_arrays(factors)
        stack = np.empty(max(len(self.ops), 1))
        return np.array([not disallowed(point, centre, half, kinds, self.ops, self.args, self.bounds, stack)
                         for point in np.asarray(points, dtype=float)], dtype=bool)


def factor_arrays(factors: tuple[DesignFactor, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each factor's centre and half range in its units (0 and 1 for categorical) and its kernel kind."""
    centre = np.array([0.0 if isinstance(f, CategoricalFactor) else 0.5 * (f.low + f.high) for f in factors])
    half = np.array([1.0 if isinstance(f, CategoricalFactor) else 0.5 * (f.high - f.low) for f in factors])
    kinds = np.array([CATEGORICAL if isinstance(f, CategoricalFactor) else NUMERIC for f in factors], dtype=np.int64)
    return centre, half, kinds


def compile_restrictions(disallowed: tuple[str, ...], constraints: tuple[str, ...], factors: tuple[DesignFactor, ...],
                         where: str, blind: str | None = None) -> Restrictions:
    """Check and compile the expressions; DesignError names the field, the expression and what is wrong.

    `blind` names the blinded factor, which no expression may mention (the public spec holds them).
    """
    ops: list[int] = []
    args: list[float] = []
    bounds = [0]
    for field, expressions, negate in (("disallowed", disallowed, False), ("constraints", constraints, True)):
        for i, text in enumerate(expressions):
            label = f"{where} {field}[{i}] {text!r}"
            program = _Compiler(factors, label, blind).expression(text)
            if negate:
                program.append((NOT, 0.0))
            ops += [op for op, _ in program]
            args += [arg for _, arg in program]
            bounds.append(len(ops))
    return Restrictions(tuple(disallowed), tuple(constraints), np.array(ops, dtype=np.int64),
                        np.array(args, dtype=float), np.array(bounds, dtype=np.int64))


class _Compiler:
    """One expression to a postfix program of (opcode, argument) pairs."""

    def __init__(self, factors: tuple[DesignFactor, ...], where: str, blind: str | None) -> None:
        self.index = {f.name: i for i, f in enumerate(factors)}
        self.factors = factors
        self.where = where
        self.blind = blind
        self.text = ""

    def fail(self, what: str) -> DesignError:
        return DesignError(f"{self.where}: {what}")

    def expression(self, text: str) -> list[tuple[int, float]]:
        if not isinstance(text, str) or not text.strip():
            raise self.fail("expected a non-empty string")
        if len(text) > MAX_LENGTH:
            raise self.fail(f"longer than {MAX_LENGTH} characters")
        self.text = text
        try:
            tree = ast.parse(text, mode="eval")
        except SyntaxError as exc:
            raise self.fail(f"not an expression ({exc.msg})") from None
        return self.boolean(tree.body)

    def boolean(self, node: ast.expr) -> list[tuple[int, float]]:
        if isinstance(node, ast.BoolOp):
            op = AND if isinstance(node.op, ast.And) else OR
            program = self.boolean(node.values[0])
            for value in node.values[1:]:
                program += [*self.boolean(value), (op, 0.0)]
            return program
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return [*self.boolean(node.operand), (NOT, 0.0)]
        if isinstance(node, ast.Compare):
            return self.compare(node)
        raise self.fail(f"expected a comparison (==, !=, <, <=, >, >=, in) joined by and, or, not; got {ast.unparse(node)!r}")

    def compare(self, node: ast.Compare) -> list[tuple[int, float]]:
        program: list[tuple[int, float]] = []
        left = node.left
        for i, (op, right) in enumerate(zip(node.ops, node.comparators)):
            program += self.pair(left, op, right)
            if i:
                program.append((AND, 0.0))
            left = right
        return program

    def pair(self, left: ast.expr, op: ast.cmpop, right: ast.expr) -> list[tuple[int, float]]:
        categorical = self.categorical(left) or self.categorical(right)
        if isinstance(op, (ast.In, ast.NotIn)):
            if not isinstance(right, (ast.List, ast.Tuple, ast.Set)) or not right.elts:
                raise self.fail(f"'in' needs a list of values, got {ast.unparse(right)!r}")
            program = []
            for j, element in enumerate(right.elts):
                program += self.pair(left, ast.Eq(), element)
                if j:
                    program.append((OR, 0.0))
            return program + ([(NOT, 0.0)] if isinstance(op, ast.NotIn) else [])
        if type(op) not in _COMPARE:
            raise self.fail(f"unsupported comparison {type(op).__name__} (use ==, !=, <, <=, >, >=, in, not in)")
        if categorical is not None:
            if not isinstance(op, (ast.Eq, ast.NotEq)):
                raise self.fail(f"{categorical.name} is categorical: compare it with == or != (or in) only")
            name, other = (left, right) if self.categorical(left) else (right, left)
            if not (isinstance(other, ast.Constant) and isinstance(other.value, str)):
                raise self.fail(f"{categorical.name} is categorical: compare it with one of its levels "
                                f"{list(categorical.levels)} in quotes")
            if other.value not in categorical.levels:
                raise self.fail(f"{other.value!r} is no level of {categorical.name} (levels: {', '.join(categorical.levels)})")
            return [(VAR, float(self.index[categorical.name])), (CONST, float(categorical.levels.index(other.value))),
                    (_COMPARE[type(op)], 0.0)]
        return [*self.number(left), *self.number(right), (_COMPARE[type(op)], 0.0)]

    def categorical(self, node: ast.expr) -> CategoricalFactor | None:
        if isinstance(node, ast.Name) and node.id in self.index:
            if node.id == self.blind:
                raise self.fail(f"{node.id} is blinded: no expression in the public spec may name it")
            factor = self.factors[self.index[node.id]]
            if isinstance(factor, CategoricalFactor):
                return factor
        return None

    def finite(self, node: ast.Constant) -> float:
        """A number written in the expression as the float the programs hold: one too large for a float (a
        400-digit integer, 1e999) is refused, never turned into infinity or an OverflowError."""
        try:
            value = float(node.value)
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            written = ast.get_source_segment(self.text, node) or ast.unparse(node)
            shown = written if len(written) <= 24 else f"{written[:20]}... ({len(written)} characters)"
            raise self.fail(f"the number {shown} is too large: numbers must be finite, below about 1.8e308 in magnitude")
        return value

    def number(self, node: ast.expr) -> list[tuple[int, float]]:
        if isinstance(node, ast.Name):
            if node.id == self.blind:
                raise self.fail(f"{node.id} is blinded: no expression in the public spec may name it")
            if node.id not in self.index:
                raise self.fail(f"no design factor {node.id!r} (design factors: {', '.join(self.index)})")
            if self.categorical(node) is not None:
                raise self.fail(f"{node.id} is categorical: compare it with its level names, not in arithmetic")
            return [(VAR, float(self.index[node.id]))]
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return [(CONST, self.finite(node))]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            inner = self.number(node.operand)
            return [*inner, (NEG, 0.0)] if isinstance(node.op, ast.USub) else inner
        if isinstance(node, ast.BinOp) and type(node.op) in _ARITHMETIC:
            return [*self.number(node.left), *self.number(node.right), (_ARITHMETIC[type(node.op)], 0.0)]
        raise self.fail(f"expected a factor name, a number or arithmetic (+ - * /) of them; got {ast.unparse(node)!r}")
