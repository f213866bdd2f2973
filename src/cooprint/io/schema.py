"""Field-by-field checks of parsed JSON / TOML data, each failure one line with the field's path.

A file read with :func:`json.loads` or :mod:`tomllib` is plain dicts, lists, strings and numbers;
anything can stand anywhere. The checks here take a value, the file it came from (``where``) and
the path of the value inside it (``robots[1].start``), and either return the value in the type the
caller needs or raise :class:`SchemaError`::

    job.json: robots[1].start: expected 3 finite numbers within +-1e+06, got [0, "a"]
    m.toml: robots[1].facing: unknown key (did you mean 'facing_deg'?)
    m.toml: robots[1].colour: unknown key; expected one of: name, program, start, facing_deg

Values are shown short (:func:`show`: at most a few items and levels, long strings clipped), so a
10 MB string or a list nested 10,000 deep never ends up whole in a message.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Iterable, Mapping

from cooprint.errors import UserError


class SchemaError(UserError):
    """A value in a JSON or TOML file that is not what its field needs."""


def show(value: Any, depth: int = 2, items: int = 4, chars: int = 40, total: int = 120) -> str:
    """``value`` as short JSON-like text: strings quoted and clipped, at most ``items`` items per
    list or object and ``depth`` levels, ``NaN``/``Infinity`` as JSON writes them; at most
    ``total`` characters in all."""
    text = _show(value, depth, items, chars)
    return text if len(text) <= total else text[:total] + "..."


def _show(value: Any, depth: int, items: int, chars: int) -> str:
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "null"}[value]
    if isinstance(value, str):
        text = value if len(value) <= chars else value[:chars] + "..."
        return '"' + text.encode("unicode_escape").decode("ascii").replace('"', '\\"') + '"'
    if isinstance(value, float):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity") if math.isinf(value) \
            else repr(value)
    if isinstance(value, int):
        if value.bit_length() < 64:
            return str(value)
        return f"a whole number of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    if isinstance(value, (list, tuple)):
        if depth <= 0:
            return "[...]" if value else "[]"
        inner = [_show(v, depth - 1, items, chars) for v in value[:items]]
        return "[" + ", ".join(inner + (["..."] if len(value) > items else [])) + "]"
    if isinstance(value, Mapping):
        if depth <= 0:
            return "{...}" if value else "{}"
        keys = list(value)[:items]
        inner = [f"{_show(str(k), 0, items, chars)}: {_show(value[k], depth - 1, items, chars)}" for k in keys]
        return "{" + ", ".join(inner + (["..."] if len(value) > items else [])) + "}"
    return type(value).__name__


def key_path(path: str, key: str | int) -> str:
    """The path of a member: ``robots`` + 1 -> ``robots[1]``; ``settings`` + ``robot`` ->
    ``settings.robot``."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def shown_key(key: str, chars: int = 40) -> str:
    """A key as a message shows it: control and non-ASCII characters escaped, clipped."""
    text = key[:chars].encode("unicode_escape").decode("ascii")
    return text + ("..." if len(key) > chars else "")


def did_you_mean(key: str, known: Iterable[str]) -> str:
    """`` (did you mean 'facing_deg'?)`` when ``key`` is close to a known key, else ``""``."""
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def fail(where: str, path: str, what: str, value: Any = ..., ) -> SchemaError:
    """The error for field ``path`` of file ``where``: ``where: path: what, got VALUE``."""
    got = "" if value is ... else f", got {show(value)}"
    return SchemaError(f"{where}: {path}: {what}{got}" if path else f"{where}: {what}{got}")


def check_object(value: Any, where: str, path: str, *, required: Iterable[str] = (),
                 optional: Iterable[str] = (), unknown: str = "error") -> dict[str, Any]:
    """``value`` must be an object (a JSON object, a TOML table) with every ``required`` key.

    ``unknown`` says what a key outside ``required`` and ``optional`` is: ``"error"`` (a file a
    person writes: a typo must not silently become a default), ``"typo"`` (a file cooprint writes,
    which a newer version may extend: unknown keys are ignored unless close to a known one, then
    an error with the known key), or ``"ignore"``.
    """
    if not isinstance(value, dict):
        raise fail(where, path, "expected an object", value)
    required, optional = list(required), list(optional)
    known = required + optional
    if unknown != "ignore":
        for k in value:
            if k in known:
                continue
            hint = did_you_mean(str(k), known)
            if unknown == "error" or hint:  # the key meant, or (none close) the keys known
                listed = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
                raise fail(where, key_path(path, shown_key(str(k))),
                           f"unknown key{hint}" if hint else f"unknown key; expected one of: {listed}")
    for k in required:
        if k not in value:
            raise fail(where, key_path(path, k), "missing")
    return value


def check_number(value: Any, where: str, path: str, *, lo: float | None = None, hi: float | None = None,
                 lo_open: bool = False, integer: bool = False, unit: str = "") -> float:
    """A finite number (not a boolean) within ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``), as float
    (as int with ``integer``)."""
    rng = []
    if lo is not None:
        rng.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    what = ("expected a whole number" if integer else "expected a finite number") + \
        (" " + " and ".join(rng) if rng else "") + (f" ({unit})" if unit else "")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(where, path, what, value)
    try:
        v = float(value)
    except OverflowError:  # an int beyond float's range
        raise fail(where, path, what, value) from None
    ok = math.isfinite(v) and (not integer or v.is_integer())
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v <= hi
    if not ok:
        raise fail(where, path, what, value)
    return int(value) if integer else v


def check_vector(value: Any, where: str, path: str, n: int, bound: float = 1e6) -> list[float]:
    """A list of ``n`` finite numbers, each within ``+-bound``."""
    what = f"expected {n} finite numbers within +-{bound:g}"
    if not isinstance(value, list) or len(value) != n:
        raise fail(where, path, what, value)
    for x in value:
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise fail(where, path, what, value)
        try:
            v = float(x)
        except OverflowError:
            raise fail(where, path, what, value) from None
        if not (math.isfinite(v) and abs(v) <= bound):
            raise fail(where, path, what, value)
    return [float(x) for x in value]


def check_list(value: Any, where: str, path: str, *, min_len: int = 0, max_len: int | None = None,
               what: str = "items") -> list[Any]:
    """A list of ``min_len`` to ``max_len`` items (their own checks are the caller's)."""
    if not isinstance(value, list) or len(value) < min_len or (max_len is not None and len(value) > max_len):
        size = f"at least {min_len}" if max_len is None else f"{min_len} to {max_len}"
        raise fail(where, path, f"expected a list of {size} {what}", value)
    return value


def check_string(value: Any, where: str, path: str, *, what: str = "a non-empty string", pattern=None,
                 max_len: int = 1000) -> str:
    """A non-empty string of at most ``max_len`` characters (matching ``pattern``, a compiled
    regular expression, when given)."""
    if not isinstance(value, str) or not value or len(value) > max_len or (
            pattern is not None and not pattern.fullmatch(value)):
        raise fail(where, path, f"expected {what}", value)
    return value


__all__ = ["SchemaError", "check_list", "check_number", "check_object", "check_string", "check_vector",
           "did_you_mean", "fail", "key_path", "show"]
