"""The valve's lands as a place of missing terms, described once: perturbations of the orifice law at its boundaries.

The grammar of :mod:`ehas_env.physics.term_grammar` makes terms that add to a balance or a signal.  At the lands the
missing physics changes the orifice law itself: a pressure at one of its boundaries that is not the one the model
holds (a return line above tank, a supply that differs at the valve, a line whose drop grows with the flow), its
gain by port, by spool direction or with the load, its metering law (a share of the flow that goes with the drop).
A pressure change ``dp`` at a land changes its flow by ``q dp / (2 drop)`` (``q ~ sqrt(drop)``), so each term is a
land's flow times a factor.  Each is one :class:`LandTerm` here -- its coefficient, unit, words, code and the range
the proposal tries -- and everything else derives from them: the term class the replays run
(:mod:`ehas_env.measurement.proposal_terms`), the effect file a proposal writes (the same lines,
:mod:`ehas_env.diagnosis.proposal`), the forms in words and the coefficients' ranges; the named forms
(:data:`LAND_FORMS`) set them for :mod:`ehas_env.diagnosis.naming`.

Examples
--------
>>> [t.coef for t in LAND_TERMS][:4]
['c_ret', 'c_sup', 'c_ga', 'c_gb']
>>> print(land_method_source().splitlines()[0][:60])
def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, c_ret,
"""
from __future__ import annotations

from dataclasses import dataclass

from ehas_env.physics.term_grammar import NamedForm, term_class


@dataclass(frozen=True)
class LandTerm:
    """One perturbation of the orifice law at the lands: a coefficient times a land's flow and a factor.

    Attributes
    ----------
    coef : str
        The coefficient's name in the term class.
    unit : str
        Its SI unit.
    words : str
        The coefficient in words (its parameter's documentation).
    form : str
        The form in words (the coefficient multiplies it).
    span : float
        The largest coefficient tried (its unit; assumed: 30-60 bar at the ports, 40-60 % of the gain, a drop of the
        supply's size at the rated flow).
    always : tuple of str
        Lines of code adding to ``dqa``, ``dqb`` whatever the spool's direction (``{c}`` the coefficient).
    pos, neg : tuple of str
        Lines run while the spool opens positive (``qc >= 0``: supply to A, B to return) and negative.
    """

    coef: str
    unit: str
    words: str
    form: str
    span: float
    always: tuple = ()
    pos: tuple = ()
    neg: tuple = ()

    @property
    def by_direction(self) -> bool:
        """Whether its code depends on the spool's direction."""
        return bool(self.pos or self.neg)


#: the least drop a land's term divides by, Pa (finite where a land closes)
_D = "1.0e5"
_IN_A, _IN_B = f"max(ps - pa, {_D})", f"max(ps - pb, {_D})"  # the inflow land's drop, spool positive / negative
_OUT_A, _OUT_B = f"max(pa, {_D})", f"max(pb, {_D})"  # the outflow land's drop to the tank
_HALF = f"(0.5 * max(ps, {_D}))"  # the rated drop, p_S / 2

#: every term of the lands' family
LAND_TERMS = (
    LandTerm("c_ret", "Pa", "back-pressure of the return line (tank above 0)",
             "the outflow land's flow times -1 / (2 p_out): return back-pressure", 30e5,
             pos=(f"dqb -= {{c}} * q_b / (2.0 * {_OUT_B})",), neg=(f"dqa -= {{c}} * q_a / (2.0 * {_OUT_A})",)),
    LandTerm("c_sup", "Pa", "supply pressure offset at the valve",
             "the inflow land's flow times 1 / (2 (p_S - p_in)): supply offset", 60e5,
             pos=(f"dqa += {{c}} * q_a / (2.0 * {_IN_A})",), neg=(f"dqb += {{c}} * q_b / (2.0 * {_IN_B})",)),
    LandTerm("c_ga", "-", "extra flow gain into or out of chamber A (relative)", "(q_A, 0)", 0.4,
             always=("dqa += {c} * q_a",)),
    LandTerm("c_gb", "-", "extra flow gain into or out of chamber B (relative)", "(0, q_B)", 0.4,
             always=("dqb += {c} * q_b",)),
    LandTerm("c_gpos", "-", "extra flow gain when the spool is open positive (relative)",
             "(q_A, q_B) while q_c >= 0", 0.4, pos=("dqa += {c} * q_a", "dqb += {c} * q_b")),
    LandTerm("c_gneg", "-", "extra flow gain when the spool is open negative (relative)",
             "(q_A, q_B) while q_c < 0", 0.4, neg=("dqa += {c} * q_a", "dqb += {c} * q_b")),
    LandTerm("c_gpl", "-", "flow gain change per unit of |p_L| / p_S (relative)", "(q_A, q_B) |p_A - p_B| / p_S",
             0.6, always=(f"dqa += {{c}} * abs(pa - pb) / max(ps, {_D}) * q_a",
                          f"dqb += {{c}} * abs(pa - pb) / max(ps, {_D}) * q_b")),
    LandTerm("c_rline", "Pa s/m^3", "resistance of the lines between valve and chambers: pressure drop per flow",
             "each land's flow times -|q| / (2 drop): line resistance", 1.5e10,
             pos=(f"dqa -= {{c}} * abs(q_a) * q_a / (2.0 * {_IN_A})",
                  f"dqb -= {{c}} * abs(q_b) * q_b / (2.0 * {_OUT_B})"),
             neg=(f"dqb -= {{c}} * abs(q_b) * q_b / (2.0 * {_IN_B})",
                  f"dqa -= {{c}} * abs(q_a) * q_a / (2.0 * {_OUT_A})")),
    LandTerm("c_rsup", "Pa s/m^3", "resistance of the supply line: supply pressure drop per supply flow",
             "the inflow land's flow times -|q_S| / (2 (p_S - p_in)): supply drop per supply flow", 1.5e10,
             pos=(f"dqa -= {{c}} * abs(q_supply) * q_a / (2.0 * {_IN_A})",),
             neg=(f"dqb -= {{c}} * abs(q_supply) * q_b / (2.0 * {_IN_B})",)),
    LandTerm("c_rsup2", "Pa s^2/m^6", "turbulent supply drop: supply pressure drop per supply flow squared",
             "the inflow land's flow times -q_S^2 / (2 (p_S - p_in)): supply drop per supply flow squared", 7.5e13,
             pos=(f"dqa -= {{c}} * q_supply ** 2 * q_a / (2.0 * {_IN_A})",),
             neg=(f"dqb -= {{c}} * q_supply ** 2 * q_b / (2.0 * {_IN_B})",)),
    LandTerm("c_lam", "-", "share of the land flow that goes with the land's drop itself, not its square root "
                           "(laminar metering; relative, at the rated drop p_S / 2)",
             "each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop", 0.5,
             pos=(f"dqa += {{c}} * q_a * (math.sqrt({_IN_A} / {_HALF}) - 1.0)",
                  f"dqb += {{c}} * q_b * (math.sqrt({_OUT_B} / {_HALF}) - 1.0)"),
             neg=(f"dqb += {{c}} * q_b * (math.sqrt({_IN_B} / {_HALF}) - 1.0)",
                  f"dqa += {{c}} * q_a * (math.sqrt({_OUT_A} / {_HALF}) - 1.0)")),
)
#: the arguments of the lands' terms: the valve's own quantities, known wherever a flow is metered (a run's line A,
#: the valve bench; :data:`~ehas_env.physics.effects.base.VALVE_SIDE_QUANTITIES`)
LAND_ARGS = ("pa", "pb", "ps", "q_a", "q_b", "qc", "q_supply")


def flow_body(terms, indent: str = "    ") -> list[str]:
    """The lines of a ``chamber_flows`` method summing ``terms`` ((LandTerm or an object with ``always``, ``pos``,
    ``neg``), coefficient expression) into ``dqa``, ``dqb`` and returning them.

    Parameters
    ----------
    terms : iterable of (LandTerm, str)
    indent : str
        The method body's indentation.

    Returns
    -------
    list of str
    """
    lines = [f"{indent}dqa = 0.0", f"{indent}dqb = 0.0"]
    pos, neg = [], []
    for t, c in terms:
        lines += [indent + ln.format(c=c) for ln in t.always]
        pos += [ln.format(c=c) for ln in t.pos]
        neg += [ln.format(c=c) for ln in t.neg]
    if pos or neg:
        lines.append(f"{indent}if qc >= 0.0:")
        lines += [f"{indent}    {ln}" for ln in pos] or [f"{indent}    pass"]
        lines.append(f"{indent}else:")
        lines += [f"{indent}    {ln}" for ln in neg] or [f"{indent}    pass"]
    return lines + [f"{indent}return dqa, dqb"]


def land_method_source() -> str:
    """The source of the lands' term method: every coefficient an argument, the term their sum.

    Returns
    -------
    str
    """
    coefs = tuple(t.coef for t in LAND_TERMS)
    return (f"def chamber_flows({', '.join(LAND_ARGS + coefs)}):\n"
            + "\n".join(flow_body((t, t.coef) for t in LAND_TERMS)) + "\n")


_LF = term_class("land_flows")


def _n(key, kind, law, words, *params, positive=()):
    return NamedForm(key, key.split(".", 1)[0], kind, law, words, tuple((p, f"{_LF}.{c}", s) for p, c, s in params),
                     positive)


#: the named forms of the lands' terms: the orifice law's gain by direction, port and load, its metering law, the
#: lines', the supply's and the return's pressures
LAND_FORMS = (
    _n("chamber_flows.gain_by_direction", "valve", "q (1 + g_+) for i >= 0, q (1 + g_-) for i < 0",
       "a valve flow gain that differs by spool direction", ("g_+", "c_gpos", 1), ("g_-", "c_gneg", 1)),
    _n("chamber_flows.gain_by_port", "valve", "q_A (1 + g_A), q_B (1 + g_B)", "a flow gain that differs by port",
       ("g_A", "c_ga", 1), ("g_B", "c_gb", 1)),
    _n("chamber_flows.gain_load", "valve", "q (1 - c |P_L| / P_S)", "a valve flow gain that falls with load pressure",
       ("c", "c_gpl", -1)),
    _n("chamber_flows.line_resistance", "leakage/flow", "p_line drop = R q", "a resistance in the lines A and B",
       ("R", "c_rline", 1), positive=("R",)),
    _n("chamber_flows.metering_law", "valve", "q ~ sqrt(drop) (1 + c (sqrt(drop / (P_S / 2)) - 1))",
       "the lands' flow departs from the orifice law with the land's drop (flow forces on the spool, a laminar "
       "share)", ("c", "c_lam", 1)),
    # supply and return
    _n("supply.offset", "supply/return", "P_S += dP_S", "the supply pressure at the valve differs from the set one",
       ("dP_S", "c_sup", 1)),
    _n("supply.line_drop", "supply/return", "P_S -= R_S Q_S", "a supply line whose drop rises with the supply flow",
       ("R_S", "c_rsup", 1), positive=("R_S",)),
    _n("supply.line_drop_turbulent", "supply/return", "P_S -= K_S Q_S^2",
       "a supply line (or filter) whose drop rises with the supply flow squared", ("K_S", "c_rsup2", 1),
       positive=("K_S",)),
    _n("return.back_pressure", "supply/return", "P_T = p_t", "a return line above tank pressure",
       ("p_t", "c_ret", 1), positive=("p_t",)),
)
