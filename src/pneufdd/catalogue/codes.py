"""Order codes of cylinders, drives, grippers and valves: what each part of a code says.

An order code (the type designation on a nameplate) names the family, the size and,
for a cylinder, the stroke, followed by options. :func:`parse_actuator_code` and
:func:`parse_valve_code` split a code into a :class:`ParsedCode`; the sizes and the
data behind them are in the package tables (:mod:`pneufdd.catalogue.tables`). Forms:

* Festo cylinders and drives: ``DSBC-63-100-PPVA-N3``, ``DNC-32-200-PPV-A``,
  ``DSNU-20-50-PPV-A``, ``ADN-25-15-A-P-A``, ``DFM-25-100-P-A-GF``, ``DGPL-25-300``,
  ``HMP-16-100``, ``SLT-10-80-A-CC-B``: family, size (bore), stroke [mm], options;
  ``DRQD-16-90``: size and swivel angle [deg]; grippers ``DHPS-16-A``, ``HGD-16-A``:
  size (the stroke is the gripper's);
* SMC cylinders: ``CP96SDB32-100C``, ``C96SDB50-200``, ``CDQ2B32-50DZ``,
  ``MGPM20-100Z``: series, letters, bore, ``-``, stroke, letters;
* ISO bore-stroke patterns: ``ISO 15552 32x100`` (also ``ISO15552-32-100``),
  ``ISO 6432 20x50``, ``ISO 21287 25x15``;
* Festo valves: ``VUVG-L14-M52-MT-G18`` (line L or S, size 10/14/18, function M52 5/2
  monostable, B52 5/2 bistable, P53C 5/3 closed centre), ``VUVS-L20-M52-MD-G18-F7``,
  ``CPE14-M1BH-5L-1/8`` (5L/5LS 5/2 monostable, 5J 5/2 bistable, 5/3G closed centre);
* SMC valves: ``SY5120-5LZD-01`` (series digit 3/5/7/9, function 1 2-position single,
  2 double, 3 closed centre).

Options the twin uses: ``S2`` (Festo) or ``W`` (SMC) through piston rod; the rest
(cushioning ``PPV``/``PPVA``/``PPS``/``P``, position sensing ``A``, ``N3``, bearings)
is kept as text. A code that does not parse raises
:class:`~pneufdd.errors.InputError` naming the code, the part that failed and the forms
allowed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from pneufdd.errors import InputError, describe

__all__ = [
    "ACTUATOR_FORMS",
    "VALVE_FORMS",
    "ParsedCode",
    "parse_actuator_code",
    "parse_valve_code",
]

ACTUATOR_FORMS = (
    "DSBC|DNC|DSNU|ADN|DFM|DGPL|HMP|SLT-<bore>-<stroke>[-options]",
    "DRQD-<size>-<angle>[-options]",
    "DHPS|HGD-<size>-A[-options]",
    "CP96|C96<letters><bore>-<stroke>[letters]",
    "C[D]Q2<letters><bore>-<stroke>[letters]",
    "MGP<M|L|A><bore>-<stroke>[letters]",
    "ISO 15552|6432|21287 <bore>x<stroke>",
)
"""The forms of actuator order codes accepted (docs/catalogue.md)."""
VALVE_FORMS = (
    "VUVG-<L|S><10|14|18>-<M52|B52|P53C>[-options]",
    "VUVS-L<20|25|30>-<M52|J52|B52|P53C>[-options]",
    "CPE<10|14|18|24>-M1BH-<5L|5LS|5J|5/3G>[-options]",
    "SY<3|5|7|9><1|2|3><2|4>0[-options]",
)
"""The forms of valve order codes accepted."""
MAX_CODE_LENGTH = 80
MAX_STROKE_MM = 10_000.0

_FESTO = re.compile(
    r"^(?P<family>DSBC|DNC|DSNU|ADN|DFM|DGPL|HMP|SLT)-(?P<size>[^-]+)-(?P<stroke>[^-]+)"
    r"(?P<options>(?:-[^-]+)*)$"
)
_DRQD = re.compile(r"^DRQD-(?P<size>[^-]+)-(?P<angle>[^-]+)(?P<options>(?:-[^-]+)*)$")
_GRIPPER = re.compile(r"^(?P<family>DHPS|HGD)-(?P<size>[^-]+)(?P<options>(?:-[^-]+)*)$")
_SMC_ISO = re.compile(
    r"^(?P<family>CP96|C96)(?P<letters>[A-Z]*?)(?P<size>\d+)-(?P<stroke>\d+(?:\.\d+)?)"
    r"(?P<suffix>[A-Z]*)(?P<options>(?:-.+)?)$"
)
_CQ2 = re.compile(
    r"^C(?P<magnet>D?)Q2(?P<letters>[A-Z]*?)(?P<size>\d+)-(?P<stroke>\d+(?:\.\d+)?)"
    r"(?P<suffix>[A-Z]*)(?P<options>(?:-.+)?)$"
)
_MGP = re.compile(
    r"^MGP(?P<letters>[MLA])(?P<size>\d+)-(?P<stroke>\d+(?:\.\d+)?)(?P<suffix>[A-Z]*)"
    r"(?P<options>(?:-.+)?)$"
)
_ISO = re.compile(
    r"^ISO[ _-]?(?P<standard>15552|6432|21287)[ _:-]+(?P<size>\d+(?:\.\d+)?)\s*[XX*/-]\s*"
    r"(?P<stroke>\d+(?:\.\d+)?)(?P<options>.*)$"
)
_VUVG = re.compile(
    r"^VUVG-(?P<line>L|S|LK|SK|B|BK)(?P<size>\d+)A?-(?P<function>[^-]+)(?P<options>(?:-.+)?)$"
)
_VUVS = re.compile(r"^VUVS-(?P<line>L|LK|J)(?P<size>\d+)-(?P<function>[^-]+)(?P<options>(?:-.+)?)$")
_CPE = re.compile(r"^CPE(?P<size>\d+)-M1BH-(?P<function>[^-]+)(?P<options>(?:-.+)?)$")
_SY = re.compile(r"^SY(?P<size>\d)(?P<function>\d)(?P<mount>\d)0(?P<options>(?:-.+)?)$")


@dataclass(frozen=True)
class ParsedCode:
    """An order code split into its parts.

    Attributes
    ----------
    code : str
        The code as given (stripped, upper case).
    family : str
        Family as the tables name it (``DSBC``, ``ISO15552``, ``VUVG``, ``SY``, ...).
    size : str
        Size as the tables name it (``63``; ``L14`` for VUVG; ``5000`` for SY).
    stroke_mm : float or None
        Stroke in the code [mm] (cylinders).
    angle_deg : float or None
        Swivel angle [deg] (semi-rotary drives).
    function : str
        Valve function in the code (``M52``, ``5/3G``, ``1``); empty for actuators.
    through_rod : bool
        A through piston rod (``S2``, SMC ``W``).
    options : tuple of str
        The remaining parts, as text.
    """

    code: str
    family: str
    size: str
    stroke_mm: float | None = None
    angle_deg: float | None = None
    function: str = ""
    through_rod: bool = False
    options: tuple[str, ...] = ()


def _clean(code: object, what: str) -> str:
    if not isinstance(code, str) or not code.strip():
        raise InputError(describe(f"{what} order code", code, "a non-empty text"))
    text = " ".join(code.strip().upper().split())
    if len(text) > MAX_CODE_LENGTH:
        raise InputError(
            describe(f"{what} order code", text[:40] + "...", f"at most {MAX_CODE_LENGTH} chars")
        )
    return text


def _number(code: str, part: str, text: str, low: float, high: float) -> float:
    """A positive number in a code, or an error naming the code and the part."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not low <= value <= high:  # also nan
        raise InputError(
            describe(f"{part} of order code {code!r}", text, f"a number from {low:g} to {high:g}")
        )
    return value


def _options(text: str) -> tuple[str, ...]:
    return tuple(p for p in text.strip("-").split("-") if p)


def parse_actuator_code(code: str) -> ParsedCode:
    """Split an actuator's order code into family, size, stroke (or angle) and options.

    Parameters
    ----------
    code : str
        The order code, e.g. ``"DSBC-63-100-PPVA-N3"`` or ``"ISO 15552 32x100"``.

    Returns
    -------
    ParsedCode

    Raises
    ------
    InputError
        Naming the code, the part that failed and the forms allowed.

    Examples
    --------
    >>> p = parse_actuator_code("DSBC-63-100-PPVA-N3")
    >>> p.family, p.size, p.stroke_mm, p.options
    ('DSBC', '63', 100.0, ('PPVA', 'N3'))
    >>> parse_actuator_code("CDQ2B32-50DZ").stroke_mm
    50.0
    >>> parse_actuator_code("iso 15552 32x100").family
    'ISO15552'
    """
    text = _clean(code, "actuator")
    m = _FESTO.match(text)
    if m is not None:
        opts = _options(m["options"])
        stroke = _number(text, "stroke", m["stroke"], 1.0, MAX_STROKE_MM)
        return ParsedCode(text, m["family"], m["size"], stroke, None, "", "S2" in opts, opts)
    m = _DRQD.match(text)
    if m is not None:
        angle = _number(text, "swivel angle", m["angle"], 1.0, 360.0)
        return ParsedCode(text, "DRQD", m["size"], None, angle, "", False, _options(m["options"]))
    m = _GRIPPER.match(text)
    if m is not None:
        return ParsedCode(text, m["family"], m["size"], options=_options(m["options"]))
    for pattern, family in ((_SMC_ISO, ""), (_CQ2, "CQ2"), (_MGP, "MGP")):
        m = pattern.match(text)
        if m is not None:
            stroke = _number(text, "stroke", m["stroke"], 1.0, MAX_STROKE_MM)
            letters = m["letters"] + "/" + m["suffix"]
            through = "W" in m["letters"] or m["suffix"].startswith("W")
            return ParsedCode(
                text,
                family or m["family"],
                m["size"],
                stroke,
                None,
                "",
                through,
                (letters, *_options(m["options"])),
            )
    m = _ISO.match(text.replace("×", "X"))
    if m is not None:
        size = _number(text, "bore", m["size"], 1.0, 500.0)
        stroke = _number(text, "stroke", m["stroke"], 1.0, MAX_STROKE_MM)
        return ParsedCode(
            text, f"ISO{m['standard']}", f"{size:g}", stroke, options=_options(m["options"])
        )
    family = re.split(r"[-\d ]", text, maxsplit=1)[0] or text
    raise InputError(
        describe(f"family of actuator order code {text!r}", family, list(ACTUATOR_FORMS))
    )


_VALVE_FUNCTIONS = {
    "VUVG": ("M52", "B52", "P53C", "P53E", "P53U", "T32C", "T32U", "T32H", "M32C", "M32U"),
    "VUVS": ("M52", "J52", "B52", "P53C", "P53E", "P53U", "M32C", "M32U"),
    "CPE": ("5L", "5LS", "5J", "5/3G", "5/3E", "5/3B", "3GL", "3OL", "3GLS", "3OLS"),
    "SY": ("1", "2", "3", "4", "5"),
}
"""Every function a family's code may name (the twin's kinds come from the tables)."""


def parse_valve_code(code: str) -> ParsedCode:
    """Split a directional valve's order code into family, size and function.

    Parameters
    ----------
    code : str
        E.g. ``"VUVG-L14-P53C-T-G14"``, ``"CPE14-M1BH-5/3G-1/8"``, ``"SY5120-5LZD-01"``.

    Returns
    -------
    ParsedCode
        ``size`` as the tables name it (``L14``, ``14``, ``5000``), ``function``.

    Raises
    ------
    InputError
        Naming the code, the part that failed and the forms allowed.

    Examples
    --------
    >>> p = parse_valve_code("VUVG-L14-P53C-T-G14")
    >>> p.family, p.size, p.function
    ('VUVG', 'L14', 'P53C')
    >>> parse_valve_code("SY5120-5LZD-01").size
    '5000'
    """
    text = _clean(code, "valve")
    for family, pattern in (("VUVG", _VUVG), ("VUVS", _VUVS), ("CPE", _CPE), ("SY", _SY)):
        m = pattern.match(text)
        if m is None:
            continue
        function = m["function"]
        if function not in _VALVE_FUNCTIONS[family]:
            raise InputError(
                describe(
                    f"valve function of order code {text!r}", function, _VALVE_FUNCTIONS[family]
                )
            )
        if family in ("VUVG", "VUVS"):
            size = ("S" if m["line"].startswith("S") else "L") + m["size"]
        elif family == "SY":
            size = f"{m['size']}000"
        else:
            size = m["size"]
        return ParsedCode(text, family, size, function=function, options=_options(m["options"]))
    family = re.split(r"[-\d ]", text, maxsplit=1)[0] or text
    raise InputError(describe(f"family of valve order code {text!r}", family, list(VALVE_FORMS)))
