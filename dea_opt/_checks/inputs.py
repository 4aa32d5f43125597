"""Boundary checks shared by the public constructors: each raises a named InputError."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError


def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


#: Largest magnitude of any dimensional input (mm, N, N mm, MPa, rad), and smallest magnitude of
#: one that sets a scale (an area, a thickness, a modulus, a nonzero load). The arithmetic
#: multiplies up to about eight of them (a stiffness V H / h^2 times a lever arm squared, an
#: energy, their sums over up to 1e9 springs), and within these bounds every such product
#: stays far inside float64 (1e+-308): nothing overflows to inf, underflows to 0, or becomes
#: subnormal. They are far beyond any joint: 1e30 mm is 1e11 light years.
LARGEST = 1e30
SMALLEST = 1e-30


def check_range(name: str, arr, unit: str = "", *, positive: bool = False) -> None:
    """Raise :class:`InputError` unless every ``|value| <= LARGEST`` and, with ``positive``,
    every value is ``>= SMALLEST`` (a scale); ``arr`` is already finite."""
    arr = np.asarray(arr, dtype=float)
    flat = arr.reshape(-1)
    unit = f" {unit}" if unit else ""
    big = np.flatnonzero(np.abs(flat) > LARGEST)
    if big.size:
        i = int(big[0])
        raise InputError(
            f"{name} must be at most {LARGEST:g}{unit} in magnitude (products of such values overflow "
            f"float64), got {flat[i]:g}{_at(arr, i)}"
        )
    if positive:
        small = np.flatnonzero(flat < SMALLEST)
        if small.size:
            i = int(small[0])
            raise InputError(
                f"{name} must be at least {SMALLEST:g}{unit} (it divides and sets a scale; smaller "
                f"values underflow float64), got {flat[i]:g}{_at(arr, i)}"
            )


def _at(arr: np.ndarray, flat_index: int) -> str:
    if arr.ndim == 0:
        return ""
    index = tuple(int(i) for i in np.unravel_index(flat_index, arr.shape))
    return f" at index {index[0] if len(index) == 1 else index}"


def as_numeric(name: str, value) -> np.ndarray:
    """``value`` as a float array of any shape (the caller checks shape and values); an
    :class:`InputError` naming ``name`` when it is not numeric."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numbers (an array of floats), got {_describe(value)}") from None


def as_float_array(name: str, value, shape: tuple, *, allow_scalar_for=None) -> np.ndarray:
    """``value`` as a float64 C-contiguous array of ``shape`` (``None`` entries free).

    With ``allow_scalar_for=n`` a scalar is broadcast to shape ``(n,)``.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numeric with shape {_shape(shape)}, got {_describe(value)}") from None
    if allow_scalar_for is not None and arr.ndim == 0:
        arr = np.full(allow_scalar_for, float(arr))
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise InputError(f"{name} must have shape {_shape(shape)}, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        index = np.argwhere(bad)[0]
        raise InputError(f"{name} must be finite, got {arr[tuple(index)]} at index {tuple(int(i) for i in index)}")
    return np.ascontiguousarray(arr)


def _shape(shape) -> str:
    inner = ", ".join("N" if s is None else str(s) for s in shape)
    return f"({inner},)" if len(shape) == 1 else f"({inner})"


def vector3(name: str, value, unit: str = "mm") -> tuple:
    """A finite 3-vector of magnitude at most :data:`LARGEST` per component, as a tuple."""
    if value is None:
        value = (0.0, 0.0, 0.0)
    if np.ndim(value) == 0:
        try:
            if float(value) == 0.0:
                value = (0.0, 0.0, 0.0)
        except (TypeError, ValueError):
            pass
    arr = as_float_array(name, value, (3,))
    check_range(name, arr, unit)
    return tuple(float(v) for v in arr)


def finite_number(name: str, value, unit: str = "") -> float:
    """A finite number of magnitude at most :data:`LARGEST`."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number, got {_describe(value)}") from None
    if not math.isfinite(v):
        raise InputError(f"{name} must be finite, got {v}")
    check_range(name, v, unit)
    return v


def number_in_range(name: str, value, low=None, high=None, *, low_open: bool = False) -> float:
    """``value`` as a float, finite and in range, or an InputError naming ``name`` and the range.

    ``low <= value`` (``low < value`` with ``low_open``) and ``value <= high``; a bound
    that is None is not checked. Only real numbers are taken: a bool or a string is an
    error, not a number.
    """
    from numbers import Real

    if low is not None and high is not None and not low_open:
        expected = f"a finite number in [{low:g}, {high:g}]"
    else:
        bounds = ([f"{'>' if low_open else '>='} {low:g}"] if low is not None else []) + (
            [f"<= {high:g}"] if high is not None else []
        )
        expected = " ".join(["a finite number", " and ".join(bounds)]).strip()
    ok = not isinstance(value, bool) and isinstance(value, Real) and math.isfinite(value)
    if ok and low is not None:
        ok = value > low if low_open else value >= low
    if not ok or (high is not None and value > high):
        raise InputError(f"{name} must be {expected}, got {value!r}")
    return float(value)


def positive_integer(name: str, value) -> int:
    """``value`` as an int >= 1 (an integral float is accepted), or a named InputError."""
    if isinstance(value, bool) or int(value) != value or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}")
    return int(value)
