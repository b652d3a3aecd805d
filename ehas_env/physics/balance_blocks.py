"""Static blocks at the model's balances: a term of a balance's local quantity, each kind defined once (issue 43).

The followers and the reading blocks of :mod:`ehas_env.physics.augment` act where a signal passes on; a rig's
missing physics as often acts *inside a balance*: a spring that meets a gap (a force beyond some stroke), a relief
or a seal that cracks open above a pressure (a flow beyond it), a friction that holds a level once the crank moves
(a torque that saturates with the rate), a drag that hardens (a cubic).  Each is a term ``t(q)`` of one local
quantity ``q`` added to one balance: the block-oriented (Hammerstein-Wiener) nonlinearity estimators a MATLAB user
knows (dead zone, saturation, polynomial), put inside the physical model where they act.

* **Places** (:data:`BALANCE_PLACES`): every balance the model computes with each of its own rate-setting local
  quantities -- the piston's force balance with the piston's velocity, the crank's torque balance with its rate,
  each chamber's flow balance with its pressure, and the pressures at the valve's supply and return lands with the
  valve's opening (a chain the lands meter between: ``lands`` of the compiled model), and each land's flow out of its
  port with that flow (the chain after the orifice law, ``land_flows``).  A place is one
  :class:`BalancePlace` (what the balance returns, which quantity, their units and typical sizes on the rig, their
  words); its quantity must be one the model defines where that balance's terms are called (checked against
  :data:`~ehas_env.physics.effects.base.PLACE_QUANTITIES`), so a place the model cannot compute is refused.
* **Kinds** (:data:`BALANCE_KINDS`): :class:`Constant` (the offset block), :class:`Proportional` (the linear
  block), :class:`Beyond` (a dead zone: zero
  within +-k, rising with a slope beyond), :class:`Saturating` (proportional within +-k, a constant level beyond:
  friction-like), :class:`Cubic` (a hardening or softening term), :class:`Knee` (piecewise-linear: two slopes
  meeting at +-k).  A kind is one class with its law (an expression
  of the quantity ``u``, its parameters and the place's scale ``S``), its parameters (sized by the place), words
  and residual signature.

The product is registered as hypothesis effects ``aug_<stem>_<place>`` (:func:`balance_blocks`) and tried by the
diagnosis' state stage after the followers and reading blocks, fitted inside the full model and judged as they are;
a user's kind or place is a subclass or one :class:`BalancePlace` and a call of :meth:`BalanceStatic.at`.

Examples
--------
>>> from ehas_env.physics.effects import get_effect
>>> get_effect("aug_beyond_crank_rate").in_words({"c": -2.8, "k": 5.8})
'a term beyond +-5.8 rad/s of the crank rate, -2.8 N m per 10 rad/s beyond it, added to the crank torque balance'
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.optimize import minimize_scalar

from ehas_env.physics.effects.augmentation import Augmentation, fmt_interval, kind_at
from ehas_env.physics.effects.base import LOCALS, PLACE_QUANTITIES, Param


@dataclass(frozen=True)
class BalancePlace:
    """A balance of the model and one local quantity a missing term there may be a function of.

    Attributes
    ----------
    place : str
        The model's place whose term the block is (``piston_force``, ``crank_torque``, ``chamber_flows``).
    short : str
        The place in an effect's name (``aug_<kind>_<short>``).
    quantity : str
        The local quantity, an argument the model defines where the place's terms are called (``v``, ``omega``,
        ``pa`` ...).
    q_unit, q_span, q_shown : str, float, (float, str)
        The quantity's SI unit, its typical span on the rig (the book's: +-30 deg at 3 Hz is 10 rad/s at the
        crank, 0.5 m/s at the piston; the pressures up to the supply's 100-200 bar), and how words show it
        (factor from the SI unit, unit).
    out_unit, out_span, out_shown : str, float, (float, str)
        What the balance's term is (N, N m, m^3/s, Pa), the size of the largest missing term there (assumed: a
        tenth of the piston's stall force of about 50 kN, 5 kN; that force at the 50 mm crank, 250 N m; the valve's
        rated 25 L/min at a chamber; 30 bar at the lands, a tenth of a 300-bar supply), and how words show it.
    returns : str
        The place's return value with the term ``t`` in it (``"t"``; a chamber's flow: ``"t, 0.0"``).
    where : str
        The balance in words ("the crank torque balance").
    words : str
        The quantity in words ("the crank rate").
    centred : bool
        Whether the quantity swings about zero (a rate, a velocity); an absolute pressure does not, and a term
        beyond +-k of it is a term above k.
    """

    place: str
    short: str
    quantity: str
    q_unit: str
    q_span: float
    q_shown: tuple
    out_unit: str
    out_span: float
    out_shown: tuple
    returns: str
    where: str
    words: str
    centred: bool = True
    #: the values a place of a chain passes on, which its term gets and returns (the lands' pressures: ``p_sup``,
    #: ``p_ret``); () for a balance's sum
    chain: tuple = ()
    #: the term's variable ``u`` as an expression of ``quantity`` ("" for the quantity itself; the lands': the flow
    #: through them whatever its direction, ``abs(qc)``)
    value: str = ""


_LPM = LOCALS["qc"].shown
_BAR = LOCALS["p_load"].shown
#: each balance's local quantities besides its own (BALANCE_PLACES' first four): what its law in the model's
#: derivatives reads (ehas_env.physics.codegen): the piston's force A p_load moves a body whose position sets the
#: crank's geometry; the crank's torque acts at its angle; a chamber's pressure rises with the flow in less its
#: expansion A v and leaks across the piston with p_load.  A friction that rises with the load pressure, a spring or
#: a cushion with the position, a leak across the piston.  Each quantity's unit, span and words:
#: :data:`~ehas_env.physics.effects.base.LOCALS`
OTHER_LOCALS = {"piston_velocity": ("x", "p_load"), "crank_rate": ("theta",), "chamber_a": ("p_load", "v"),
                "chamber_b": ("p_load", "v")}


def with_local(place: "BalancePlace", quantity: str) -> "BalancePlace":
    """The balance of ``place`` with another of its local quantities
    (:data:`~ehas_env.physics.effects.base.LOCALS`), as a place of its own, ``<body>_<quantity's name>`` (e.g.
    ``piston_load_pressure``, ``chamber_a_velocity``).

    Parameters
    ----------
    place : BalancePlace
        A balance with its own quantity.
    quantity : str
        An argument the model defines where the balance's terms are called (``x``, ``theta``, ``p_load``, ``v``).

    Returns
    -------
    BalancePlace

    Examples
    --------
    >>> with_local(BALANCE_PLACES[0], "p_load").short
    'piston_load_pressure'
    """
    q = LOCALS[quantity]
    body = place.short if place.place == "chamber_flows" else place.short.split("_")[0]
    return BalancePlace(place.place, f"{body}_{q.name}", quantity, q.unit, q.span, q.shown, place.out_unit,
                        place.out_span, place.out_shown, place.returns, place.where, q.words)


def _own(place: str, short: str, quantity: str, out_unit: str, out_span: float, out_shown: tuple, returns: str,
         where: str, words: str = "", **kw) -> BalancePlace:
    """A balance with its own rate-setting quantity, described by :data:`~ehas_env.physics.effects.base.LOCALS`
    (``words`` where the place reads it otherwise: the lands' opening, either way)."""
    q = LOCALS[quantity]
    return BalancePlace(place, short, quantity, q.unit, q.span, q.shown, out_unit, out_span, out_shown, returns,
                        where, words or q.words, **kw)


#: every balance of the model with its own rate-setting local quantity (the piston's force with its velocity, the
#: crank's torque with its rate, each chamber's flow with its pressure), then with the other quantities its law
#: reads (OTHER_LOCALS)
_OWN_PLACES = (
    _own("piston_force", "piston_velocity", "v", "N", 5.0e3, (1.0, "N"), "t", "the piston force balance"),
    _own("crank_torque", "crank_rate", "omega", "N m", 250.0, (1.0, "N m"), "t", "the crank torque balance"),
    _own("chamber_flows", "chamber_a", "pa", "m^3/s", 25.0 / 60000.0, _LPM, "t, 0.0", "chamber A's flow balance",
         centred=False),
    _own("chamber_flows", "chamber_b", "pb", "m^3/s", 25.0 / 60000.0, _LPM, "0.0, t", "chamber B's flow balance",
         centred=False),
    # the pressures the valve's lands meter between, each with the flow through the supply and the return line:
    # the valve's opening as no-load flow, whichever way it opens (a line's drop or a back pressure grows with the
    # flow through it, whatever its direction)
    _own("land_pressures", "supply", "qc", "Pa", 3.0e6, _BAR, "p_sup + t, p_ret",
         "the supply pressure at the valve's lands", "the valve's opening (as no-load flow, either way)",
         centred=False, chain=("p_sup", "p_ret"), value="abs(qc)"),
    _own("land_pressures", "return", "qc", "Pa", 3.0e6, _BAR, "p_sup, p_ret + t",
         "the return pressure at the valve's lands", "the valve's opening (as no-load flow, either way)",
         centred=False, chain=("p_sup", "p_ret"), value="abs(qc)"),
    # each land's flow out of its port (a chain after the orifice law: ``lands`` of the compiled model), with that
    # flow itself: a land that passes more or less than the law says (a worn edge, a leak past the land), which
    # the flow meter in line A sees as the chamber does
    _own("land_flows", "land_a", "q_a", "m^3/s", 25.0 / 60000.0, _LPM, "q_a + t, q_b",
         "land A's flow (out of the valve's port A)", chain=("q_a", "q_b")),
    _own("land_flows", "land_b", "q_b", "m^3/s", 25.0 / 60000.0, _LPM, "q_a, q_b + t",
         "land B's flow (out of the valve's port B)", chain=("q_a", "q_b")),
)
BALANCE_PLACES = _OWN_PLACES + tuple(with_local(p, q) for p in _OWN_PLACES for q in OTHER_LOCALS.get(p.short, ()))


def check_place(place: BalancePlace) -> BalancePlace:
    """``place``, or a one-line ValueError when the model does not compute its quantity where that balance's terms
    are called (:data:`~ehas_env.physics.effects.base.PLACE_QUANTITIES`): no such place."""
    if place.quantity not in PLACE_QUANTITIES.get(place.place, ()) or not set(place.chain) <= PLACE_QUANTITIES.get(
            place.place, set()):
        raise ValueError(f"balance place {place.short}: the model has no '{place.quantity}' at {place.place} (it "
                         f"has {', '.join(sorted(PLACE_QUANTITIES.get(place.place, ()))) or 'no such place'})")
    return place


for _p in BALANCE_PLACES:
    check_place(_p)


class BalanceStatic(Augmentation):
    """A kind of static term at a balance: ``t = expr(u)`` of the place's local quantity ``u``, its parameters and
    the place's scale ``S`` (no state).  :meth:`at` puts it at a :class:`BalancePlace`."""

    #: the term, a Python expression of the quantity ``u``, the kind's parameters and the place's scale ``S``
    expr: ClassVar[str] = ""
    stem: ClassVar[str] = ""
    kind_title: ClassVar[str] = ""
    main_param = "c"
    screen_from_defaults = False  # no state: nothing a re-opened beta or K could have taken over
    #: where this kind's break starts, a share of the quantity's largest logged magnitude (None: no break)
    break_share: ClassVar[float | None] = None

    @classmethod
    def fits(cls, place: BalancePlace) -> bool:
        """Whether the kind means something at ``place`` (every balance, unless the kind says otherwise)."""
        return True

    @classmethod
    def kind_params(cls, place: BalancePlace) -> tuple:
        """The kind's parameters at ``place``: the term's size ``c`` (signed, in the balance's unit) and, for a
        kind with a break, the break ``k`` (in the quantity's unit)."""
        c = Param("c", place.out_unit, 0.0, (-place.out_span, place.out_span),
                  f"the term's size, {place.out_unit} (signed; assumed range: +-{place.out_span:g} {place.out_unit}, "
                  "the largest missing term there the place describes: BalancePlace.out_span)",
                  typical=(1.0e-3 * place.out_span, 0.1 * place.out_span))
        if cls.break_share is None:
            return (c,)
        k = Param("k", place.q_unit, 0.5 * place.q_span, (1.0e-3 * place.q_span, 2.0 * place.q_span),
                  f"the break, {place.q_unit} (assumed range: 0.001 to 2 times the quantity's span of "
                  f"{place.q_span:g} {place.q_unit})", typical=(0.05 * place.q_span, place.q_span), log_scale=True)
        return c, k

    @classmethod
    def start_hint(cls, peak: float, peak_rate: float) -> dict:
        # the break inside the quantity's logged range (where a break the logs cannot reach would leave the size's
        # scan without effect)
        return {} if cls.break_share is None or peak <= 0.0 else {"k": cls.break_share * peak}

    @classmethod
    def at(cls, place: BalancePlace) -> type:
        """The effect ``aug_<stem>_<place.short>`` that adds this kind's term to the balance ``place``.

        Parameters
        ----------
        place : BalancePlace

        Returns
        -------
        type
            A registered subclass; its term is written as source (the compiled model copies a term's text).
        """
        name = f"aug_{cls.stem}_{place.short}"
        check_place(place)
        params = cls.kind_params(place)
        args = ", ".join([place.quantity] + [q for q in place.chain if q != place.quantity]
                         + [p.name for p in params] + ["S"])
        text = (f"def {place.place}({args}):\n    u = {place.value or place.quantity}\n    t = {cls.expr}\n"
                f"    return {place.returns}\n")
        scale = Param("S", place.q_unit, place.q_span, (0.0, 1.0e30),
                      f"the quantity's typical span on the rig, {place.q_unit} (the term's scale)")
        # the module that puts the kind there owns the effect (a user's file with a place of its own)
        return kind_at(cls, place.short, name, place.where, [text],
                       {"params": params, "constants": (scale,), "balance_place": place,
                        "shown": {"c": place.out_shown, "k": place.q_shown}},
                       module=sys._getframe(1).f_globals.get("__name__", cls.__module__))

    @classmethod
    def term(cls, q, params: dict) -> np.ndarray:
        """The term at the place's quantity's values ``q`` (SI, an array), the kind's law as the model computes it.

        Parameters
        ----------
        q : array_like
            The place's local quantity (:attr:`BalancePlace.quantity`), SI.
        params : dict
            The kind's numbers ({name: value}, SI).

        Returns
        -------
        numpy.ndarray
            The term, in the balance's unit.

        Examples
        --------
        >>> from ehas_env.physics.effects import get_effect
        >>> get_effect("aug_beyond_crank_rate").term([0.0, 6.0, -12.0], {"c": -20.0, "k": 5.0}).tolist()
        [0.0, -2.0, 14.0]
        """
        p = cls.balance_place
        ops = {"min": np.minimum, "max": np.maximum, "abs": np.abs}  # the law's scalar operations, elementwise
        u = eval(p.value or p.quantity, {"__builtins__": {}}, {**ops, p.quantity: np.asarray(q, dtype=float)})
        # the law is the class's own text (the compiled model's term), never data read from a file
        return np.broadcast_to(eval(cls.expr, {"__builtins__": {}}, {**ops, "u": u, "S": p.q_span, **params}),
                               np.shape(u)).astype(float) + 0.0  # + 0.0: no signed zero

    #: the break values tried by :meth:`nearest`, log-spaced across what the quantity reaches
    NEAREST_BREAKS = 48

    @classmethod
    def nearest(cls, q, target) -> dict:
        """The kind's numbers whose term is closest (least squares) to ``target`` at the quantity's values ``q``:
        where another kind at this place fitted a term, the start this kind's own fit takes from it (a term beyond
        a threshold from a piecewise-linear term whose slope within came out nil).  The sizes enter every
        kind's law linearly and are solved for exactly; a break is chosen on a log grid over what ``q`` reaches,
        within its range.  A kind of one's own whose law is not linear in its numbers other than ``k`` overrides
        this method (the numbers found are only a fit's start: a poor one costs a refit, never a wrong answer).

        Parameters
        ----------
        q : array_like
            The place's quantity, SI (e.g. as the model simulates the runs).
        target : array_like
            The term to imitate at ``q``, in the balance's unit.

        Returns
        -------
        dict
            {name: value} of every number of the kind, inside its range.

        Examples
        --------
        >>> from ehas_env.physics.effects import get_effect
        >>> import numpy as np
        >>> w = np.linspace(-12.0, 12.0, 241)
        >>> knee = get_effect("aug_knee_crank_rate").term(w, {"c": 0.0, "d": -25.0, "k": 5.8})
        >>> {n: round(v, 2) for n, v in get_effect("aug_beyond_crank_rate").nearest(w, knee).items()}
        {'c': -25.0, 'k': 5.8}
        """
        q, target = np.ravel(np.asarray(q, dtype=float)), np.ravel(np.asarray(target, dtype=float))
        params = cls.kind_params(cls.balance_place)
        sizes = [p for p in params if p.name != "k"]
        breaks = [None]
        brk = next((p for p in params if p.name == "k"), None)
        if brk is not None:  # a break beyond the largest |q| is no break the values can tell
            lo, hi = brk.bounds
            top = min(hi, max(float(np.max(np.abs(q), initial=0.0)), lo))
            breaks = list(np.geomspace(max(lo, 1.0e-3 * top), top, cls.NEAREST_BREAKS))

        def solved(k) -> tuple:  # (squared error, numbers) with the break at k, the sizes solved for
            fixed = {} if k is None else {"k": float(k)}
            # each size's column: the term with that size 1 and the others 0 (the law is linear in them)
            cols = np.column_stack([cls.term(q, {**{s.name: float(s is one) for s in sizes}, **fixed})
                                    for one in sizes])
            sol = [float(np.clip(v, *s.bounds)) for v, s in zip(np.linalg.lstsq(cols, target, rcond=None)[0], sizes)]
            return float(np.sum((cols @ np.array(sol) - target) ** 2)), {**{s.name: v for s, v in zip(sizes, sol)},
                                                                          **fixed}

        grid = [solved(k) for k in breaks]
        i = min(range(len(grid)), key=lambda j: grid[j][0])
        if len(breaks) < 3:
            return grid[i][1]
        # the break between the grid's neighbours of the best, to a part in a thousand of its log
        a, b = np.log(breaks[max(i - 1, 0)]), np.log(breaks[min(i + 1, len(breaks) - 1)])
        fine = minimize_scalar(lambda x: solved(np.exp(x))[0], bounds=(a, b), method="bounded",
                               options={"xatol": 1.0e-3})
        return min(grid[i], solved(float(np.exp(fine.x))), key=lambda e: e[0])[1]

    @classmethod
    def _q(cls, value: float, ci=None) -> str:
        f, unit = cls.balance_place.q_shown
        return f"{fmt_interval(value, ci, f)} {unit}"

    @classmethod
    def _c(cls, value: float, ci=None) -> str:
        f, unit = cls.balance_place.out_shown
        return f"{fmt_interval(value, ci, f)} {unit}"


class Constant(BalanceStatic):
    """A constant term (the offset block): a constant force or torque, a constant leak into or out of one chamber,
    a land that passes a constant flow more or less than the orifice law, a constant drop or back pressure at the
    lands."""

    form = "a constant term"
    stem = "const"
    kind_title = "constant term"
    expr = "c"
    explanation = "The balance gets a constant term, whatever the quantity does."
    signature = ("a residual of one sign that the loop works against on every run alike (a steady offset of the "
                 "pressures or the current that holds it), the same on small runs as on large ones.")

    @classmethod
    def fits(cls, place: BalancePlace) -> bool:
        """A constant term belongs to the balance, not to a quantity: it is put at the first of the built-in places
        of each balance (a place of one's own at a balance already there, the crank's torque with its angle, would
        be the same term again)."""
        same = [p for p in BALANCE_PLACES if (p.place, p.returns) == (place.place, place.returns)]
        return not same or same[0] == place

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a constant term of -0.64 L/min added to land A's flow (out of the valve's port A)"."""
        ci = ci or {}
        return f"a constant term of {cls._c(params['c'], ci.get('c'))} added to {cls.balance_place.where}"


class Proportional(BalanceStatic):
    """A term in proportion to the quantity (a leak from one chamber alone, a line's laminar drop, a damping at one
    balance: the linear block, where the library's laws put it at both chambers or at one body)."""

    form = "a proportional term"
    stem = "prop"
    kind_title = "proportional term"
    expr = "c * u / S"
    explanation = "The balance gets a term in proportion to the quantity."
    signature = "a residual that follows the quantity itself, in every run, in proportion to it."

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a term proportional to chamber A's pressure, -0.18 L/min per 100 bar, added to chamber A's flow
        balance"."""
        ci, p = ci or {}, cls.balance_place
        return (f"a term proportional to {p.words}, {cls._c(params['c'], ci.get('c'))} per {cls._q(p.q_span)}, "
                f"added to {p.where}")


class Beyond(BalanceStatic):
    """A term that is zero while the quantity is within +-k and rises with the slope c / S beyond (a dead zone, as
    the block-oriented nonlinearity estimators call it: a spring that meets a gap, a relief or a seal that cracks
    open above a pressure, a drag that sets in above a speed)."""

    form = "a term beyond a threshold"
    stem = "beyond"
    kind_title = "term beyond a threshold"
    expr = "c * (u - min(max(u, -k), k)) / S"
    break_share = 0.5
    explanation = ("The balance gets a term that is zero while the quantity stays within +-k and grows in "
                   "proportion to how far beyond it is: something that engages only past a threshold.")
    signature = ("a residual that appears only where the quantity passes +-k (the large, fast runs' peaks), none "
                 "on the small runs, and grows with the excess.")

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a term beyond +-5.8 rad/s of the crank rate, -2.8 N m per 10 rad/s beyond it, added to the crank
        torque balance" (an absolute pressure: "above 45 bar")."""
        ci, p = ci or {}, cls.balance_place
        side = "beyond +-" if p.centred else "above "
        return (f"a term {side}{cls._q(params['k'], ci.get('k'))} of {p.words}, {cls._c(params['c'], ci.get('c'))} "
                f"per {cls._q(p.q_span)} {'beyond' if p.centred else 'above'} it, added to {p.where}")


class Saturating(BalanceStatic):
    """A term proportional to the quantity within +-k that holds its level c beyond (a saturation: a friction
    that holds its level once the part moves, a flow that a restriction limits)."""

    form = "a saturating term"
    stem = "saturating"
    kind_title = "saturating term"
    expr = "c * min(max(u / k, -1.0), 1.0)"
    break_share = 0.2

    explanation = ("The balance gets a term that grows with the quantity up to +-k and holds the level c beyond: "
                   "a friction-like or a limited term.")
    signature = ("a residual that changes sign with the quantity and keeps the same level on every run beyond "
                 "+-k (the small runs as much as the large ones).")

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a saturating term of the crank rate, -2.8 N m reached at +-0.5 rad/s, added to the crank torque
        balance"."""
        ci, p = ci or {}, cls.balance_place
        return (f"a saturating term of {p.words}, {cls._c(params['c'], ci.get('c'))} reached at "
                f"{'+-' if p.centred else ''}{cls._q(params['k'], ci.get('k'))}, added to {p.where}")


class Cubic(BalanceStatic):
    """A term in the cube of the quantity (a smooth nonlinearity: a drag or a spring that hardens, a leak that
    grows faster than the pressure)."""

    form = "a cubic term"
    stem = "cubic"
    kind_title = "cubic term"
    expr = "c * (u / S) ** 3"
    explanation = ("The balance gets a term in the cube of the quantity: small near zero, steep at the largest "
                   "values.")
    signature = "a residual at the quantity's largest values on the large runs, growing as its cube."
    #: the share of the quantity's span S the runs may reach (assumed: a rig whose valve opens to 8.6 of its rated
    #: 25 L/min, 0.34): the size, the term at S, must hold the largest term there (BalancePlace.out_span) where
    #: they do, (1 / REACH)^3 = 27 times it
    REACH = 1.0 / 3.0

    @classmethod
    def kind_params(cls, place: BalancePlace) -> tuple:
        """The size ``c``, the term at one span ``S``: up to the largest term there at a third of the span
        (27 times :attr:`BalancePlace.out_span`), typically 9 times the other kinds' (a term of their typical size
        at a third of the span)."""
        (c,) = super().kind_params(place)
        m = round(cls.REACH ** -3)
        return (Param("c", c.unit, 0.0, (m * c.bounds[0], m * c.bounds[1]),
                      f"the term's size at one span S, {place.out_unit} (signed; assumed range: +-{m:g} x "
                      f"{place.out_span:g} {place.out_unit}, the largest missing term there the place describes, "
                      "BalancePlace.out_span, reached at a third of the span)",
                      typical=(m / 3.0 * c.typical[0], m / 3.0 * c.typical[1])),)

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a cubic term of the piston velocity, -454 N at 0.5 m/s, added to the piston force balance"."""
        ci, p = ci or {}, cls.balance_place
        return (f"a cubic term of {p.words}, {cls._c(params['c'], ci.get('c'))} at {cls._q(p.q_span)}, added to "
                f"{p.where}")


class Knee(BalanceStatic):
    """A term proportional to the quantity whose slope changes beyond +-k (piecewise-linear: the simplest of the
    nonlinearity estimators of a Hammerstein-Wiener model, put at a balance; a damping that steepens once a seal's
    lip or a relief's poppet is passed, a line's drop that turns from laminar to steeper).  It holds the
    proportional term (``d`` = 0), the term beyond a threshold (``c`` = 0) and a saturation (``d`` = -``c``): the
    state stage keeps the simplest of them its refits cannot part from it (:func:`ehas_env.diagnosis.states
    ._refined_choice`)."""

    form = "a piecewise-linear term"
    stem = "knee"
    kind_title = "piecewise-linear term"
    expr = "(c * u + d * (u - min(max(u, -k), k))) / S"
    break_share = 0.5
    explanation = ("The balance gets a term in proportion to the quantity within +-k, whose slope changes by d / S "
                   "beyond it: two slopes meeting at a break.")
    signature = ("a residual that follows the quantity on every run and grows faster (or slower) beyond +-k: on "
                 "the large, fast runs' peaks more than in proportion.")

    @classmethod
    def kind_params(cls, place: BalancePlace) -> tuple:
        """The slope within (``c``, the term at one span ``S``), the change of slope beyond the break (``d``, the
        same unit: the term added at one span beyond it) and the break ``k``."""
        c, k = super().kind_params(place)
        d = Param("d", place.out_unit, 0.0, c.bounds,
                  f"the change of the term's slope beyond the break, {place.out_unit} per span S beyond it (signed; "
                  f"assumed range as the size's: +-{place.out_span:g} {place.out_unit})", typical=c.typical)
        return c, d, k

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a piecewise-linear term of the piston velocity, -538 N per 0.5 m/s within +-0.345 m/s and -1.08e+03 N
        per 0.5 m/s more beyond, added to the piston force balance"."""
        ci, p = ci or {}, cls.balance_place
        per = f"per {cls._q(p.q_span)}"
        within, beyond = ("within +-", "beyond") if p.centred else ("below ", "above")  # an absolute pressure
        return (f"a piecewise-linear term of {p.words}, {cls._c(params['c'], ci.get('c'))} {per} {within}"
                f"{cls._q(params['k'], ci.get('k'))} and {cls._c(params['d'], ci.get('d'))} {per} more {beyond}, "
                f"added to {p.where}")


#: the kinds of static term at a balance, each applied at every balance place it fits
BALANCE_KINDS = (Constant, Proportional, Beyond, Saturating, Cubic, Knee)
BALANCE_BLOCKS = tuple(kind.at(place) for kind in BALANCE_KINDS for place in BALANCE_PLACES if kind.fits(place))


def balance_blocks() -> list[str]:
    """The names of every static kind at every balance place (:data:`BALANCE_KINDS` x :data:`BALANCE_PLACES`),
    and those a user's file made with :meth:`BalanceStatic.at`, in the order they registered.

    Returns
    -------
    list of str
        E.g. ``aug_beyond_chamber_a``, ``aug_saturating_crank_rate``, ``aug_cubic_piston_velocity``.

    Examples
    --------
    >>> names = balance_blocks()
    >>> "aug_beyond_chamber_a" in names and "aug_cubic_piston_velocity" in names
    True
    """
    from ehas_env.physics.effects.base import REGISTRY

    return [n for n, c in REGISTRY.items() if isinstance(getattr(c, "balance_place", None), BalancePlace)
            and issubclass(c, BalanceStatic)]
