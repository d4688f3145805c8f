"""Unit helpers for the edges of the model (presets, examples, CLI).

Inside pvgraph everything is SI. These helpers convert the units hydraulic engineers quote:
``bar(13.5)`` -> Pa, ``lpm(16.3)`` -> m^3/s, ``mm(7)`` -> m, ``mm2(3.5)`` -> m^2, ``cm3(8)`` -> m^3,
``cm(5)`` -> m, ``cm2(20)`` -> m^2, ``rpm(1500)`` -> rad/s, ``cm3_per_rev(28)`` -> m^3/rad (a
displacement). ``to_bar``, ``to_lpm``, ``to_mm``, ``to_mm2`` and ``to_rpm`` convert back for
reporting.

Quantities with units are accepted wherever a parameter is given: ``to_unit("150 bar", "Pa")``
is 1.5e7, ``to_unit("10 L/min", "m^3/s")`` 1.67e-4, and a pint Quantity converts the same way.
Every :class:`~pvgraph.component.Params` field converts such values to the unit its description
declares in brackets and refuses a quantity of the wrong dimension by name. For display,
:func:`display` turns SI values into bar, L/min and mm (the one convention of the command line;
``--si`` keeps SI).
"""

from __future__ import annotations

import functools
import math
import re

from .errors import ParameterError

BAR = 1e5
LPM = 1e-3 / 60.0
MM = 1e-3
MM2 = 1e-6
CM3 = 1e-6
LITRE = 1e-3


def bar(value):
    """Pressure in bar -> Pa."""
    return value * BAR


def to_bar(value):
    """Pressure in Pa -> bar."""
    return value / BAR


def lpm(value):
    """Flow in L/min -> m^3/s."""
    return value * LPM


def to_lpm(value):
    """Flow in m^3/s -> L/min."""
    return value / LPM


def mm(value):
    """Length in mm -> m."""
    return value * MM


def to_mm(value):
    """Length in m -> mm."""
    return value / MM


def mm2(value):
    """Area in mm^2 -> m^2."""
    return value * MM2


def to_mm2(value):
    """Area in m^2 -> mm^2."""
    return value / MM2


def cm3(value):
    """Volume in cm^3 -> m^3."""
    return value * CM3


def cm(value):
    """Length in cm -> m."""
    return value * 1e-2


def cm2(value):
    """Area in cm^2 -> m^2."""
    return value * 1e-4


def rpm(value):
    """Shaft speed in rev/min -> rad/s."""
    return value * (2.0 * math.pi / 60.0)


def to_rpm(value):
    """Shaft speed in rad/s -> rev/min."""
    return value / (2.0 * math.pi / 60.0)


def cm3_per_rev(value):
    """Displacement in cm^3/rev -> m^3/rad."""
    return value * CM3 / (2.0 * math.pi)


def litre(value):
    """Volume in L -> m^3."""
    return value * LITRE


def deg(value):
    """Angle in degrees -> rad."""
    return math.radians(value)


def circle_area(diameter):
    """Area of a circle of the given diameter [m] -> [m^2]."""
    return math.pi * diameter**2 / 4.0


def lpm_per_bar(value):
    """Laminar flow constant in L/(min bar) -> m^3/(s Pa)."""
    return value * LPM / BAR


# ---------------------------------------------------------------------------------------------
# Quantities with units: "150 bar", "0.5 L", "10 L/min", pint quantities
#
# A unit is parsed into (factor to SI, dimension exponents over m, kg, s, A, K). Grammar:
# products by space, "*" or "·", quotients by "/" (binding the next factor only, as in
# "m^3/(s Pa)"), powers by "^", "**" or a trailing integer ("mm2", "cm3"), parentheses.

_DIMS = ("m", "kg", "s", "A", "K")
_ONE = (0, 0, 0, 0, 0)


def _dim(m=0, kg=0, s=0, A=0, K=0):
    return (m, kg, s, A, K)


#: symbol -> (factor to SI, dimension, takes SI prefixes)
_UNITS = {
    "m": (1.0, _dim(m=1), True), "g": (1e-3, _dim(kg=1), True), "s": (1.0, _dim(s=1), True),
    "A": (1.0, _dim(A=1), True), "K": (1.0, _dim(K=1), False),
    "N": (1.0, _dim(m=1, kg=1, s=-2), True), "Pa": (1.0, _dim(m=-1, kg=1, s=-2), True),
    "J": (1.0, _dim(m=2, kg=1, s=-2), True), "W": (1.0, _dim(m=2, kg=1, s=-3), True),
    "V": (1.0, _dim(m=2, kg=1, s=-3, A=-1), True), "Hz": (1.0, _dim(s=-1), True),
    "ohm": (1.0, _dim(m=2, kg=1, s=-3, A=-2), True), "Ω": (1.0, _dim(m=2, kg=1, s=-3, A=-2), True),
    "H": (1.0, _dim(m=2, kg=1, s=-2, A=-2), True), "C": (1.0, _dim(s=1, A=1), False),
    "L": (1e-3, _dim(m=3), True), "l": (1e-3, _dim(m=3), True),
    "bar": (BAR, _dim(m=-1, kg=1, s=-2), True),
    "psi": (6894.757293168361, _dim(m=-1, kg=1, s=-2), False),
    "atm": (101325.0, _dim(m=-1, kg=1, s=-2), False),
    "min": (60.0, _dim(s=1), False), "h": (3600.0, _dim(s=1), False),
    "lpm": (LPM, _dim(m=3, s=-1), False), "gpm": (3.785411784e-3 / 60.0, _dim(m=3, s=-1), False),
    "cc": (1e-6, _dim(m=3), False), "in": (0.0254, _dim(m=1), False),
    "t": (1e3, _dim(kg=1), False),                           # tonne
    "St": (1e-4, _dim(m=2, s=-1), True),                     # stokes: "32 cSt"
    "P": (0.1, _dim(m=-1, kg=1, s=-1), True),                # poise: "30 cP"
    "rad": (1.0, _ONE, False), "deg": (math.pi / 180.0, _ONE, False),
    "rpm": (2.0 * math.pi / 60.0, _dim(s=-1), False), "rev": (2.0 * math.pi, _ONE, False),
    "%": (0.01, _ONE, False), "-": (1.0, _ONE, False), "1": (1.0, _ONE, False),
    # US customary and engineering units of data sheets (exact definitions, NIST SP 811)
    "ft": (0.3048, _dim(m=1), False), "lb": (0.45359237, _dim(kg=1), False),
    "lbm": (0.45359237, _dim(kg=1), False),
    "lbf": (0.45359237 * 9.80665, _dim(m=1, kg=1, s=-2), False),
    "kgf": (9.80665, _dim(m=1, kg=1, s=-2), False),
    "hp": (0.45359237 * 9.80665 * 0.3048 * 550.0, _dim(m=2, kg=1, s=-3), False),
    "gal": (3.785411784e-3, _dim(m=3), False),                # US gallon
    "Nm": (1.0, _dim(m=2, kg=1, s=-2), True),                # "N m" written together, "kNm"
    "percent": (0.01, _ONE, False),
    "RPM": (2.0 * math.pi / 60.0, _dim(s=-1), False),
    "rps": (2.0 * math.pi, _dim(s=-1), False),
    "r": (2.0 * math.pi, _ONE, False),                        # revolution, "r/min" (ISO)
    "hr": (3600.0, _dim(s=1), False),
    "inch": (0.0254, _dim(m=1), False), "inches": (0.0254, _dim(m=1), False),
    "foot": (0.3048, _dim(m=1), False), "feet": (0.3048, _dim(m=1), False),
    "USgpm": (3.785411784e-3 / 60.0, _dim(m=3, s=-1), False),
    # the spellings of data sheets that cannot be misread (no SI prefix is upper case P, B or L
    # before these letters)
    "PSI": (6894.757293168361, _dim(m=-1, kg=1, s=-2), False),
    "BAR": (BAR, _dim(m=-1, kg=1, s=-2), False), "Bar": (BAR, _dim(m=-1, kg=1, s=-2), False),
    "LPM": (LPM, _dim(m=3, s=-1), False), "GPM": (3.785411784e-3 / 60.0, _dim(m=3, s=-1), False),
    "degree": (math.pi / 180.0, _ONE, False), "degrees": (math.pi / 180.0, _ONE, False),
    "turn": (2.0 * math.pi, _ONE, False), "turns": (2.0 * math.pi, _ONE, False),
    "revs": (2.0 * math.pi, _ONE, False),
}
#: units that count an angle (a power of the radian, which is dimensionless in SI): the
#: parser carries their angle exponent beside the dimension, see :func:`to_unit`
_ANGLE = {"rad": 1, "deg": 1, "rev": 1, "rpm": 1, "RPM": 1, "rps": 1, "r": 1, "degree": 1,
          "degrees": 1, "turn": 1, "turns": 1, "revs": 1}
#: characters read as the notation they stand for ("mm²", "m/s²", "90°")
_SPELLED = {"²": "^2", "³": "^3", "°": " deg", "⁻¹": "^-1"}
_PREFIXES = {"p": 1e-12, "n": 1e-9, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "m": 1e-3, "c": 1e-2,
             "d": 1e-1, "k": 1e3, "M": 1e6, "G": 1e9}
#: names of the dimensions people meet, for messages
_KINDS = {
    _dim(m=-1, kg=1, s=-2): "a pressure", _dim(m=3): "a volume", _dim(m=3, s=-1): "a volume flow",
    _dim(m=1): "a length", _dim(m=2): "an area", _dim(s=1): "a time",
    _dim(m=1, kg=1, s=-2): "a force",
    _dim(kg=1): "a mass", _dim(m=-3, kg=1): "a density", _dim(m=1, s=-1): "a velocity",
    _dim(s=-1): "a frequency", _ONE: "dimensionless", _dim(kg=1, s=-2): "a stiffness",
    _dim(kg=1, s=-1): "a damping coefficient", _dim(m=4, kg=-1, s=1): "a laminar flow conductance",
    _dim(m=2, kg=1, s=-3, A=-1): "a voltage", _dim(A=1): "a current", _dim(m=2, s=-1): "a "
    "kinematic viscosity", _dim(m=-1, kg=1, s=-1): "a dynamic viscosity",
}

_NUMBER_ONLY = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$")
#: digits in groups of three split by a space (ISO 80000-1: "1 500 kg", "15 000 N/m")
_GROUPED = re.compile(r"^(\s*[+-]?\d{1,3}(?:[ \u2009\u202f]\d{3})+)(?=\D|$)")


class _Number:
    """``_NUMBER_ONLY`` with the digit groups of the number joined first: ``match(text)``
    gives the number and the unit after it as groups 1 and 2."""

    @staticmethod
    def match(text):
        if not isinstance(text, str):
            return None
        m = _GROUPED.match(text)
        if m:
            text = re.sub(r"[ \u2009\u202f]", "", m.group(1)) + text[m.end():]
        return _NUMBER_ONLY.match(text)


_NUMBER = _Number()
_TOKEN = re.compile(r"\s*(\*\*|[()*/^·.]|[+-]?\d+|[A-Za-zµμΩ%_]+\d*)")


class UnitError(ParameterError, ValueError):
    """A unit that cannot be parsed, or a quantity of the wrong dimension."""


def kind(dim) -> str:
    """A readable name of a dimension (``"a pressure"``), or its exponents over m, kg, s, A, K."""
    if dim in _KINDS:
        return _KINDS[dim]
    return "[" + " ".join(f"{b}^{e}" if e != 1 else b for b, e in zip(_DIMS, dim) if e) + "]"


def _symbol(name: str):
    if name in _UNITS:
        return _UNITS[name][:2] + (_ANGLE.get(name, 0),)
    for prefix, scale in _PREFIXES.items():
        rest = name[len(prefix):]
        if name.startswith(prefix) and rest in _UNITS and _UNITS[rest][2]:
            f, d = _UNITS[rest][:2]
            return scale * f, d, _ANGLE.get(rest, 0)
    raise UnitError(f"unknown unit {name!r}{_close_units(name)}")


#: spellings of units met on data sheets and in other languages, by their lower case
_MISSPELT = {"mn": "min", "min": "min", "mins": "min", "hr": "h", "hrs": "h", "sec": "s",
             "secs": "s", "ltr": "L", "lt": "L", "litre": "L", "liter": "L", "litres": "L",
             "liters": "L", "l": "L"}


def _close_units(name: str) -> str:
    """``"; did you mean 'psi'?"`` for a unit written in another case or close to a known
    one, else ``""``."""
    import difflib
    if name.lower() in _MISSPELT:                      # "mn" (French), "Min", "hrs"
        return f"; did you mean {_MISSPELT[name.lower()]!r}?"
    for prefix, scale in {**_PREFIXES, "K": 1e3}.items():   # "kpsi", "Krpm", "mdeg"
        rest = name[len(prefix):]
        if name.startswith(prefix) and rest in _UNITS and not _UNITS[rest][2]:
            return (f"; {rest!r} takes no SI prefix ({prefix!r}): write the number in {rest!r} "
                    f"('{scale:g} {rest}' for '1 {name}')")
    if name.startswith("h") and name[1:] in _UNITS:   # hecto is not among the prefixes
        return f"; the prefix 'h' (hecto) is not read: write '100 {name[1:]}' for '1 {name}'"
    same = [u for u in _UNITS if u.lower() == name.lower()]
    if name.isupper() and name.lower() not in same:     # "MM": the millimetre, first
        try:
            _symbol(name.lower())
            same.append(name.lower())
        except UnitError:
            pass
    for prefix in _PREFIXES:        # "MPA", "kpa", "KPA": a prefixed unit in another case
        for written in {prefix, prefix.upper()} - ({"M"} if prefix == "m" else set()):
            if name.startswith(written) and len(name) > len(written):
                rest = name[len(written):].lower()
                same += [prefix + u for u, (_, _, pre) in _UNITS.items()
                         if pre and u.lower() == rest]
    close = list(dict.fromkeys(same)) or [
        u for u in difflib.get_close_matches(name, list(_UNITS), n=3, cutoff=0.75)
        if not (name.startswith(u) and name[len(u):][:1].isupper())]   # "degC" is no "deg"
    return f"; did you mean {' or '.join(map(repr, close))}?" if close else ""


def parse_unit(text: str) -> tuple[float, tuple]:
    """``(factor to SI, dimension)`` of a unit string: ``parse_unit("L/min") == (1/60000, ...)``."""
    return _parse(text)[:2]


def angle_power(text: str) -> int:
    """The power of the angle in a unit: 1 in ``"rad/s"`` and ``"rpm"``, -1 in ``"cm^3/rev"``,
    0 in ``"Hz"`` and ``"1/min"`` (SI counts the radian as dimensionless; this does not)."""
    return _parse(text)[2]


@functools.lru_cache(maxsize=512)
def _parse(text: str) -> tuple[float, tuple, int]:
    """``(factor to SI, dimension, angle power)`` of a unit string."""
    src = str(text).strip()
    if re.search(r"\(\s*[gGaA]\s*\)", src) or \
            re.fullmatch(r"(?i)(bar|psi|[km]?pa)\s*([ga]|abs|gauge)", src):   # "bara", "bar abs"
        raise UnitError(f"unit {text!r}: a gauge or absolute mark is not read; pressures are "
                        f"gauge here (0 = atmospheric): write the pressure above the atmosphere "
                        f"without it")
    for glyph, spelled in _SPELLED.items():
        src = src.replace(glyph, spelled)
    if src in ("", "-", "1"):
        return 1.0, _ONE, 0
    if src.startswith("/"):                         # "1500/min": per minute
        src = "1" + src
    tokens, pos = [], 0
    while pos < len(src):
        m = _TOKEN.match(src, pos)
        if not m or m.end() == pos:
            digits = re.match(r",(\d+)", src[pos:])
            if digits and len(digits.group(1)) == 3:
                # "1,500 rpm": a thousands separator, or a decimal comma
                raise UnitError(f"cannot read {text!r}: a comma is read neither as a thousands "
                                f"separator nor as a decimal point: write '1500' or '1 500' "
                                f"for fifteen hundred, '1.5' for one and a half")
            if digits:
                raise UnitError(f"cannot read {text!r}: write a decimal point, not a comma "
                                f"('0.5 L' for '0,5 L')")
            raise UnitError(f"cannot read unit {text!r} at {src[pos:]!r}")
        tokens.append(m.group(1))
        pos = m.end()
    k = [0]

    def peek():
        return tokens[k[0]] if k[0] < len(tokens) else None

    def take():
        k[0] += 1
        return tokens[k[0] - 1]

    def power(f, d, a):
        if peek() in ("^", "**"):
            take()
            exp = take() if peek() is not None else ""
            try:
                e = int(exp)
            except ValueError:
                raise UnitError(f"unit {text!r}: the exponent {exp!r} is not an integer") from None
            return f**e, tuple(x * e for x in d), a * e
        return f, d, a

    def factor():
        tok = peek()
        if tok is None:
            raise UnitError(f"unit {text!r} ends where a unit was expected")
        take()
        if tok == "(":
            f, d, a = product()
            if peek() != ")":
                raise UnitError(f"unit {text!r}: missing ')'")
            take()
        elif tok[0].isalpha() or tok[0] in "µμΩ%_":
            m2 = re.fullmatch(r"([A-Za-zµμΩ%_]+)(\d+)", tok)
            if m2 and tok not in _UNITS:            # "mm2", "cm3": a power without "^"
                f, d, a = _symbol(m2.group(1))
                e = int(m2.group(2))
                f, d, a = f**e, tuple(x * e for x in d), a * e
            else:
                f, d, a = _symbol(tok)
            nxt = peek()
            if nxt is not None and nxt.startswith("-") and nxt[1:].isdigit():
                take()                              # "min-1", "m-2": a power, ^ lost
                e = int(nxt)
                f, d, a = f**e, tuple(x * e for x in d), a * e
        elif tok == "1" and peek() == "/":         # "1/min", "1/s"
            f, d, a = 1.0, _ONE, 0
        elif tok.lstrip("+-").isdigit():
            raise UnitError(f"unit {text!r}: a number ({tok!r}) inside the unit; write the "
                            f"whole number in front of the unit (digits grouped by single "
                            f"spaces in threes are read as one number: '1 500 kg')")
        else:
            raise UnitError(f"unit {text!r}: unexpected {tok!r}")
        return power(f, d, a)

    def product():
        f, d, a = factor()
        while peek() is not None and peek() != ")":
            op = peek()
            if op in ("*", "·", "."):
                take()
                g, e, b = factor()
            elif op == "/":
                take()
                g, e, b = factor()
                g, e, b = 1.0 / g, tuple(-x for x in e), -b
            else:
                g, e, b = factor()
            f, d, a = f * g, tuple(x + y for x, y in zip(d, e)), a + b
        return f, d, a

    f, d, a = product()
    if k[0] != len(tokens):
        raise UnitError(f"unit {text!r}: unexpected {tokens[k[0]]!r}")
    return _snap(f), d, a


def _snap(f: float) -> float:
    """``f`` rounded to a short decimal when it is within a few ulps of one (cm^3 -> 1e-6)."""
    short = float(f"{f:.12g}")
    return short if abs(short - f) <= 4 * math.ulp(f) else f


def _pint_si(q) -> tuple[float, tuple, int]:
    """(magnitude in SI base units, dimension, angle power) of a pint Quantity."""
    base = q.to_base_units()
    dims = dict(q.dimensionality)
    order = ("[length]", "[mass]", "[time]", "[current]", "[temperature]")
    unknown = [k for k in dims if k not in order]
    if unknown:
        raise UnitError(f"quantity {q!r} has dimensions pvgraph does not use: {unknown}")
    d = tuple(int(dims.get(k, 0)) for k in order)
    units = getattr(base, "_units", None) or {}
    return base.magnitude, d, int(dict(units).get("radian", 0))


def is_quantity(value) -> bool:
    """True for a string with a unit (``"150 bar"``) or a pint Quantity."""
    return (isinstance(value, str) and bool(_NUMBER.match(value))) or _is_pint(value)


def _is_pint(value) -> bool:
    return all(hasattr(value, a) for a in ("magnitude", "dimensionality", "to_base_units"))


def to_unit(value, unit: str, what: str = "value") -> float:
    """``value`` (a number, ``"150 bar"`` or a pint Quantity) expressed in ``unit``.

    A plain number is taken to be in ``unit`` already; a string without a unit (``"150"``)
    only where ``unit`` has no dimension (a string is written to carry a unit: one left off
    is refused, not read as SI). A quantity of another dimension raises :class:`UnitError`
    naming ``what``, both units and both dimensions.
    """
    factor, dim, angle = _parse(unit)
    if _is_pint(value):
        si, got, got_angle = _pint_si(value)
        shown = f"{value:~P}" if hasattr(value, "__format__") else str(value)
    elif isinstance(value, str):
        m = _NUMBER.match(value)
        if not m:
            raise UnitError(f"{what} = {value!r}: {value!r} is not a number (write a number, "
                            f"or one with a unit, e.g. '150 bar')")
        number, text = float(m.group(1)), m.group(2)
        if not text:
            if any(dim) or angle:
                # a string is written to carry a unit: one without is a unit left off
                # ("150" for "150 bar" read as 150 Pa), not an SI number
                raise UnitError(
                    f"{what} = {value!r} has no unit, and {what} is {kind(dim)} [{unit}]: "
                    f"write the unit meant ('{m.group(1)} {unit}'" + (
                        f", or another such as '{m.group(1)} {_example_unit(unit)}'"
                        if _example_unit(unit) != unit and 1e-3 <= abs(number) < 1e4
                        else "") +
                    f"), or the number {m.group(1)} for {unit}")
            return number
        try:
            f, got, got_angle = _parse(text)
        except UnitError as exc:
            raise UnitError(f"{what} = {value!r}: {exc}") from None
        si, shown = number * f, value
    else:
        return value
    if got != dim:
        raise UnitError(f"{what} = {shown!r} is {kind(got)}, but {what} is {kind(dim)} "
                        f"[{unit}]")
    if got_angle != angle:
        si = _angle_reading(si, got, got_angle, angle, what, shown, unit)
    return si / factor


_EXAMPLE_UNITS = {"Pa": "bar", "m^3/s": "L/min", "m^3": "L", "m^2": "mm^2", "m": "mm",
                  "rad/s": "rpm", "rad": "deg", "m^3/rad": "cm^3/rev", "N": "kN", "kg/m^3":
                  "kg/m^3", "s": "s", "m^2/s": "cSt"}


def _example_unit(unit: str) -> str:
    """A unit an engineer writes for a quantity declared in ``unit`` (for messages)."""
    return _EXAMPLE_UNITS.get(unit, unit)


def to_si(value, what: str = "value") -> float:
    """``value`` in SI units: a number as it is, a quantity (``"6 L/min"``, a pint Quantity)
    converted by its own unit (its dimension is not checked: no unit is expected here)."""
    if _is_pint(value):
        return float(_pint_si(value)[0])
    if isinstance(value, str):
        m = _NUMBER.match(value)
        if not m:
            raise UnitError(f"{what} = {value!r}: {value!r} is not a number (write a number, "
                            f"or one with a unit, e.g. '150 bar')")
        return float(m.group(1)) * (_parse(m.group(2))[0] if m.group(2) else 1.0)
    return value


def number_in(value, unit: str, what: str = "value") -> float:
    """``value`` as a finite float in ``unit``: a number as it is, a quantity (``"50 bar"``, a
    pint Quantity) converted; a bool, anything else or a non-finite value is refused, naming
    ``what``."""
    if isinstance(value, bool):
        raise ParameterError(f"{what} = {value!r}: give a number")
    number = to_unit(value, unit or "1", what)
    try:
        number = float(number)
    except (TypeError, ValueError):
        raise ParameterError(f"{what} = {value!r}: give a number, or one with a unit "
                             f"[{unit or '-'}]") from None
    if not math.isfinite(number):
        raise ParameterError(f"{what} is not finite: {value!r}")
    return number


def _angle_reading(si, dim, got_angle, angle, what, shown, unit):
    """``si`` of a quantity whose angle power differs from the declared unit's.

    SI counts the radian as 1, so "1500 1/min" and "25 rad/s" have one dimension, but a
    rotational frequency n and an angular velocity w = 2 pi n are not the same number
    (ISO 80000-3). A frequency (Hz, 1/min, 1/s) for an angular speed is read as revolutions
    per time, an angular speed (rad/s, rpm) for a frequency [Hz] as cycles per time. Any other
    mismatch is refused: "28 cm^3" for a displacement [m^3/rad] does not say per what.
    """
    if dim == _dim(s=-1) and {got_angle, angle} == {0, 1}:
        return si * 2.0 * math.pi if angle == 1 else si / (2.0 * math.pi)
    if got_angle and not angle:
        raise UnitError(f"{what} = {shown!r} counts an angle, but {what} [{unit}] does not")
    if angle and not got_angle:
        where = "per angle" if angle < 0 else "an angle"
        example = "'... /rev' or '... /rad'" if angle < 0 else "'... deg' or '... rad'"
        raise UnitError(f"{what} = {shown!r} gives no angle, but {what} is {where} [{unit}]; "
                        f"per radian and per revolution differ by 2 pi: write it, e.g. "
                        f"{example}")
    raise UnitError(f"{what} = {shown!r}: its angle does not match {what}'s [{unit}]")


def declared_unit(description: str | None) -> str | None:
    """The unit a parameter declares in its description, ``"Orifice area [m^2]"`` -> ``"m^2"``.

    None when there is no bracket that reads as a unit (``[unit of y]``, ``[0, 1]``).
    """
    for text in re.findall(r"\[([^\[\]]*)\]", description or ""):
        try:
            parse_unit(text)
        except UnitError:
            continue
        return text
    return None


# ---------------------------------------------------------------------------------------------
# Display: one convention for people (bar, L/min, mm, L, mm^2), SI on request and in files

#: SI unit -> (display unit, factor: SI value / factor = display value)
DISPLAY_UNITS = {"Pa": ("bar", BAR), "m^3/s": ("L/min", LPM), "m": ("mm", MM),
                 "m^3": ("L", LITRE), "m^2": ("mm^2", MM2), "m/s": ("mm/s", MM),
                 "m^3/(s Pa)": ("L/(min bar)", LPM / BAR),
                 "rad/s": ("rpm", 2.0 * math.pi / 60.0),
                 "m^3/rad": ("cm^3/rev", 1e-6 / (2.0 * math.pi))}


def display(value, unit: str, si: bool = False):
    """``(value, unit)`` in the units people read (bar, L/min, mm ...), or unchanged if ``si``."""
    if si or unit not in DISPLAY_UNITS:
        return value, unit
    shown, factor = DISPLAY_UNITS[unit]
    return value / factor, shown


def format_value(value: float, unit: str, si: bool = False, digits: int = 6) -> str:
    """``"83.9 bar"``: a value in display units (or SI with ``si=True``)."""
    v, u = display(value, unit, si)
    return f"{v:.{digits}g} {u}".rstrip()
