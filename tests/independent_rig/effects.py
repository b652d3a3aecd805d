"""The effects the independent generator can switch on, with their physical kind and magnitudes.

Three groups:

* **out-of-library** effects (:data:`OUT_OF_LIBRARY`): physics of hydraulic servo
  drives described by Merritt (*Hydraulic Control Systems*, 1967) and Jelali &
  Kroll (*Hydraulic Servo-systems: Modelling, Identification and Control*, 2003)
  that ehas's effect library (``ehas effects``: coulomb, viscous and Stribeck
  friction, internal and external leakage, valve deadband, null bias and
  dynamics, transport delay, supply droop from pump + accumulator, piston mass,
  backlash, bulk modulus) does not hold;
* **unlisted** classes (:data:`UNLISTED`, issue 33 item 7): physics that neither the
  library, nor the diagnosis' structural hypotheses (``ehas_env/physics/effects/hyp_*.py``),
  nor the out-of-library group describes, spread over the model's places (:data:`PLACES`);
  each also says where it acts (``places``), for the judge of "right place";
* **library** effects re-implemented here from their definitions in
  docs/reference-model.md (:data:`LIBRARY`), for the "found as today" check.

Every parameter is given in the unit shown (``unit``) and converted to SI with
``si`` before the physics (:mod:`.physics`) reads it.  ``magnitudes`` are the
two values the acceptance set hides (a mild and a strong one; "assumed" values
typical of the literature's examples, scaled to the rig).  ``kind`` is the
effect's physical kind, one of :data:`KINDS`; ``accept`` the kinds a diagnosis may
name for it and still be judged "physically right" (the primary kind, plus a
kind whose term is the same physics seen from another place, stated in ``why``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

KINDS = ("friction", "leakage/flow", "compliance", "geometry/area", "valve", "sensor", "command path", "load",
         "fluid property", "supply/return")
#: the model's places where a physical term acts (the diagnosis' vocabulary: docs/measurement-format.md)
PLACES = ("valve_current", "coil_current", "chamber_flows", "piston_force", "crank_torque", "supply", "return",
          "position_reading")


@dataclass(frozen=True)
class P:
    """One parameter: name, unit, SI factor, the two hidden magnitudes (mild, strong), meaning."""

    name: str
    unit: str
    si: float
    magnitudes: tuple
    doc: str


@dataclass(frozen=True)
class EffectSpec:
    """An effect of the independent generator.

    Parameters
    ----------
    name : str
        Its name in campaigns and tables.
    kind : str
        Physical kind (one of :data:`KINDS`).
    params : tuple of P
        Its parameters; the first is the main one.
    source : str
        Where the physics is described.
    doc : str
        The law, in words and symbols.
    accept : tuple of str
        Kinds a diagnosis may name and still be right (the first is ``kind``).
    why : str
        Why the other accepted kinds are the same physics.
    library : bool
        Whether ehas's library holds this effect (re-implemented here).
    bench : bool
        Whether it acts on the valve flow bench too.
    extra : dict
        Free-form notes.
    places : tuple of str
        Places of the model (:data:`PLACES`) where a diagnosis may name it and be right (the first is where it
        acts); empty for the older groups, which are judged by kind only.
    """

    name: str
    kind: str
    params: tuple
    source: str
    doc: str
    accept: tuple = ()
    why: str = ""
    library: bool = False
    bench: bool = False
    extra: dict = field(default_factory=dict)
    places: tuple = ()

    @property
    def accepted_kinds(self) -> tuple:
        return (self.kind,) + tuple(k for k in self.accept if k != self.kind)

    def values(self, level: int) -> dict:
        """Parameter values (in their units) at magnitude ``level`` (0 mild, 1 strong)."""
        return {p.name: p.magnitudes[level] for p in self.params}


MJ = "Merritt 1967; Jelali & Kroll 2003"

OUT_OF_LIBRARY = {e.name: e for e in (
    EffectSpec("single_rod", "geometry/area",
               (P("alpha", "-", 1.0, (0.9, 0.75), "rod-side area over piston-side area A_B / A_A"),),
               "Merritt §6.3 (unequal-area actuator); Jelali & Kroll §3.4 (differential cylinder)",
               "A_A = A, A_B = alpha A: force A_A P_A - A_B P_B, volumes V_A = A_A (h + x) + V_d, "
               "V_B = A_B (h - x) + V_d, flows A_A x' and A_B x'",
               accept=("geometry/area",)),
    EffectSpec("return_pressure", "leakage/flow",
               (P("p_t", "bar", 1e5, (5.0, 15.0), "tank (return-line) pressure"),),
               "Merritt §5.2 (valve flow with return pressure); Jelali & Kroll §3.2",
               "the outflow land discharges to p_t instead of 0: Q_out = q_c sqrt((P_out - p_t) / (dp_n / 2))",
               accept=("leakage/flow",), bench=True),
    EffectSpec("entrained_air", "fluid property",
               (P("eps", "%", 1e-2, (3.0, 10.0), "free air volume fraction at 1 bar"),),
               "Merritt §2.3 (effective bulk modulus with entrained air); Jelali & Kroll §3.3",
               "pressure-dependent bulk modulus: 1/beta_e = (1 - a)/beta + a/(1.4 p), air fraction "
               "a = eps (1 bar / p)^(1/1.4) / (1 + eps (1 bar / p)^(1/1.4)), per chamber",
               accept=("fluid property", "compliance"),
               why="a softer oil column is a compliance of the hydraulic spring"),
    EffectSpec("load_compliance", "compliance",
               (P("k", "N/mm", 1e3, (80000.0, 25000.0), "stiffness of the load path between piston and crank "
                                                       "(rod, eye, mounting); below about 15000 N/mm the series "
                                                       "resonance with 7 sets destabilises the book's controller"),),
               "Merritt §6.5 (structural compliance between actuator and load); Jelali & Kroll §3.5",
               "the piston (5 kg) and the crank are two bodies joined by a spring k with damping "
               "c = 0.2 x 2 sqrt(k m): the LVDT reads the piston",
               accept=("compliance", "fluid property"),
               why="a spring in series with the oil column lowers the same hydraulic natural frequency "
                   "as a lower bulk modulus"),
    EffectSpec("crank_unbalance", "load",
               (P("G", "N m", 1.0, (25.0, 80.0), "unbalance torque m g l of the discs' centre of mass"),),
               "Merritt §6.4 (gravity/spring load on the actuator); Jelali & Kroll §3.5 (external load)",
               "torque on the crank -G sin(theta + 60 deg): a mass off-centre, 60 deg from the bottom at mid-stroke",
               accept=("load",)),
    EffectSpec("lugre_friction", "friction",
               (P("Fc", "N", 1.0, (150.0, 450.0), "sliding (Coulomb) level; Fs = 1.6 Fc breakaway, vs = 5 mm/s, "
                                                 "sigma0 = 1e6 N/m, sigma1 = 1e3 N s/m, sigma2 = 300 N s/m"),),
               "Canudas de Wit et al. 1995 (LuGre) as in Jelali & Kroll §3.6",
               "bristle state z' = v - sigma0 |v| z / g(v), g = Fc + (Fs - Fc) exp(-(v/vs)^2); "
               "F = -(sigma0 z + sigma1 z' + sigma2 v) on the piston",
               accept=("friction",)),
    EffectSpec("valve_direction_gain", "valve",
               (P("g", "-", 1.0, (0.06, 0.15), "relative flow-gain difference: K (1 + g sign(i))"),),
               "Merritt §5.3 (unmatched valve, asymmetric flow gain); Jelali & Kroll §3.2",
               "the valve's no-load flow settles to K i (1 + g sign(i))",
               accept=("valve",), bench=True),
    EffectSpec("valve_underlap", "valve",
               (P("u0", "LPM", 1e-3 / 60, (0.3, 0.7), "underlap of each land, as no-load flow at the rated drop "
                                                   "(from about 1 LPM the book's controller limit-cycles with 7 sets)"),),
               "Merritt §5.4 (underlapped four-way valve); Jelali & Kroll §3.2 (leakage around null)",
               "each land opens by u0 at null: P->A max(u0 + q_c, 0), A->T max(u0 - q_c, 0), same for B; "
               "every land by the square root of its drop",
               accept=("valve", "leakage/flow"),
               why="an underlapped spool is a leakage path from supply to tank through the chambers at null"),
    EffectSpec("supply_line_loss", "leakage/flow",
               (P("dp", "bar", 1e5, (8.0, 25.0), "pressure lost in the supply line at 20 LPM (turbulent, "
                                                "grows with the flow squared)"),),
               "Merritt §5.6 (supply pressure at the valve); Jelali & Kroll §3.1 (line losses)",
               "the valve's supply is Ps - dp (Q_s / 20 LPM)^2, Q_s the flow into the inflow land; "
               "the supply transducer sits at the pump (logs Ps)",
               accept=("leakage/flow", "valve"),
               why="a supply that falls with the flow is a flow gain that falls with the flow"),
    EffectSpec("lvdt_offset", "sensor",
               (P("x0", "mm", 1e-3, (0.3, 1.0), "LVDT zero offset"),),
               "Jelali & Kroll §4 (measurement errors)", "the LVDT reads x + x0", accept=("sensor",)),
    EffectSpec("lvdt_nonlinearity", "sensor",
               (P("n", "%", 1e-2, (1.0, 3.0), "cubic nonlinearity at the stroke end, of the half stroke"),),
               "Jelali & Kroll §4 (sensor nonlinearity)", "the LVDT reads x + n h (x / h)^3", accept=("sensor",)),
    EffectSpec("current_lag", "command path",
               (P("T", "ms", 1e-3, (2.0, 6.0), "time constant of the coil current (amplifier + inductance)"),),
               "Merritt §5.8 (torque motor inductance); Jelali & Kroll §3.2",
               "the valve's current lags the command: T i_v' = i - i_v", accept=("command path", "valve"),
               why="the lag is in the valve's coil, the head of the valve", bench=True),
    EffectSpec("crank_offset", "geometry/area",
               (P("phi0", "deg", 3.141592653589793 / 180, (4.0, 10.0), "crank angle at mid-stroke"),),
               "Merritt §6.4 (load kinematics)",
               "x = r (sin(theta + phi0) - sin phi0), lever r cos(theta + phi0)", accept=("geometry/area", "sensor"),
               why="the crank's zero differs from the LVDT's: a kinematic/reading error"),
    EffectSpec("disc_drag", "friction",
               (P("c", "N m s^2", 1.0, (1.0, 3.0), "turbulent (velocity-squared) drag of the discs"),),
               "Merritt §6.4 (load damping); Jelali & Kroll §3.5",
               "torque on the crank -c omega |omega|", accept=("friction",)),
    EffectSpec("turbulent_leakage", "leakage/flow",
               (P("q100", "LPM", 1e-3 / 60, (0.4, 1.2), "leakage across the piston at 100 bar (worn seal, "
                                                      "orifice-like)"),),
               "Merritt §6.2 (cross-port leakage); Jelali & Kroll §3.3 (laminar vs turbulent leakage)",
               "Q_leak = q100 sign(dp) sqrt(|dp| / 100 bar) from A to B", accept=("leakage/flow",)),
)}

#: library effects re-implemented from docs/reference-model.md (main parameter first)
LIBRARY = {e.name: e for e in (
    EffectSpec("coulomb_friction", "friction", (P("Fc", "N", 1.0, (250.0, 600.0), "Coulomb force"),),
               "docs/reference-model.md §5", "-Fc tanh(v / 1 mm/s)", accept=("friction",), library=True),
    EffectSpec("viscous_friction", "friction", (P("b", "N s/m", 1.0, (3000.0, 8000.0), "viscous coefficient"),),
               "docs/reference-model.md §5", "-b v", accept=("friction",), library=True),
    EffectSpec("transport_delay", "command path", (P("tau", "s", 1.0, (0.003, 0.006), "delay"),),
               "docs/reference-model.md §1", "current at t is the command of t - tau", accept=("command path",),
               library=True, bench=True),
    EffectSpec("valve_null_bias", "valve", (P("i_bias", "mA", 1.0, (0.4, -0.8), "null bias"),),
               "docs/reference-model.md §1", "i_v = clip(i) + i_bias", accept=("valve",), library=True, bench=True),
    EffectSpec("internal_leakage", "leakage/flow",
               (P("C_leak", "m^3/s/Pa", 1.0, (2e-12, 5e-12), "laminar leakage coefficient"),),
               "docs/reference-model.md §4", "Q_leak = C_leak (P_A - P_B)", accept=("leakage/flow",), library=True),
)}

#: library effects re-implemented here for a single check of their fit, outside the acceptance set (cases.py)
CHECKS = {e.name: e for e in (
    EffectSpec("backlash", "compliance",
               (P("delta", "mm", 1e-3, (0.1, 0.3), "half the total play 2 delta of the rod-crank joint"),),
               "docs/reference-model.md §5 and its table of constants (k_joint, c_joint, m_min)",
               "piston (5 kg) and crank are two bodies joined through a dead zone of width 2 delta: the joint "
               "pushes with k (gap - delta) + c gap' beyond +delta, k (gap + delta) + c gap' below -delta, nothing "
               "inside (k 2e7 N/m, c 3e3 N s/m); the LVDT reads the piston",
               accept=("compliance",), library=True),
)}

#: classes of hidden physics that no library effect, no structural hypothesis (ehas_env/physics/effects/hyp_*.py)
#: and no effect of :data:`OUT_OF_LIBRARY` describes (issue 33, item 7); judged by place and kind
UNLISTED = {e.name: e for e in (
    EffectSpec("bore_wear_friction", "friction",
               (P("Fw", "N", 1.0, (400.0, 1200.0), "seal friction at the stroke ends of a bore worn smooth in its "
                                                  "middle (zero at mid-stroke)"),),
               "Jelali & Kroll 2003 (cylinder friction, position-dependent through wear); "
               "Manring 2005 (actuator seal friction)",
               "F = -Fw (x / h)^2 tanh(v / 1 mm/s) on the piston: the sliding level grows with the square of the "
               "distance from mid-stroke",
               accept=("friction",), places=("piston_force",)),
    EffectSpec("end_cushion", "friction",
               (P("ce", "N s/m", 1.0, (10000.0, 40000.0), "damping of the cushions at the stroke ends"),),
               "Merritt 1967 and Manring 2005 (hydraulic cylinders: end-of-stroke cushioning)",
               "F = -ce v s^2 on the piston, s = max(0, (|x| - 0.6 h) / (0.4 h)): a damping that rises over "
               "the last 40 % of each half stroke (the cushion spear throttles the outflow)",
               accept=("friction", "leakage/flow"), places=("piston_force", "chamber_flows"),
               why="the cushion throttles the outflow near the ends: the same damping seen as a flow restriction "
                   "at the chamber"),
    EffectSpec("land_flow_forces", "valve",
               (P("gamma", "-", 1.0, (0.02, 0.06), "fall of the land's flow exponent below 1/2"),),
               "Merritt 1967 (spool valves: steady-state flow forces); Manring 2005 (spool valves: flow forces and "
               "their pressure-flow coupling)",
               "each land passes a sign(d) |d / (dp_n/2)|^(1/2 - gamma): the flow forces close the spool by a "
               "share that grows with the land's drop d (equal to the orifice law at the rated drop per land, "
               "where the bench rates the valve)",
               accept=("valve", "leakage/flow"), places=("chamber_flows", "valve_current"),
               why="a flow that departs from the orifice law with the land's drop is a flow term at the chamber"),
    EffectSpec("current_slew", "command path",
               (P("S", "mA/s", 1.0, (400.0, 150.0), "slew-rate limit of the current driver (the closed-loop runs ask "
                                                "up to about 250 mA/s, the chirp up to 1500)"),),
               "Jelali & Kroll 2003 (servo amplifier and torque-motor coil: voltage-limited current rise); "
               "Merritt 1967",
               "S_T i_v' = S tanh((i - i_v) / (S SLEW_T)): the coil current follows the command with its "
               "small-signal time constant SLEW_T = 0.2 ms but never faster than S",
               accept=("command path", "valve"), places=("valve_current", "coil_current"), bench=True,
               why="the limit is in the valve's coil driver, the head of the valve"),
    EffectSpec("lvdt_lag", "sensor",
               (P("T", "ms", 1e-3, (0.5, 2.0), "time constant of the LVDT demodulator's output filter"),),
               "Jelali & Kroll 2003 (position measurement: LVDT carrier demodulation and its output filter)",
               "the reading x_r lags the piston: T x_r' = x - x_r; the logger and the controller see x_r",
               accept=("sensor",), places=("position_reading",)),
    EffectSpec("supply_ripple", "supply/return",
               (P("a", "bar", 1e5, (3.0, 10.0), "amplitude of the pump's pressure ripple at 23.7 Hz"),),
               "Manring 2005 (axial-piston pumps: flow ripple and the supply pressure it makes); Merritt 1967",
               "Ps(t) = Ps + a sin(2 pi 23.7 Hz t) at the valve and in the logged supply pressure (the transducer "
               "sits at the pump); the flow bench has its own regulated supply",
               accept=("supply/return",), places=("supply",)),
    EffectSpec("hose_line", "compliance",
               (P("dp", "bar", 1e5, (4.0, 12.0), "laminar pressure drop of each hose at 20 LPM"),
                P("V", "cm^3", 1e-6, (20.0, 50.0), "oil volume of each hose (0.4 m or 1 m of 8 mm bore)")),
               "Merritt 1967 (hydraulic lines: lumped resistance and capacitance); Jelali & Kroll 2003",
               "a hose between each valve port and its chamber: port pressure p_v' = beta / V (Q_land - Q_h), "
               "Q_h = (p_v - p_chamber) 20 LPM / dp into the chamber; the pressure transducers sit at the "
               "actuator, the flow meter at the valve port",
               accept=("compliance", "leakage/flow", "fluid property"), places=("chamber_flows",),
               why="the hose's oil is a compliance (a softer hydraulic spring, as a lower bulk modulus) and its "
                   "resistance a flow-dependent drop on the chamber's flow"),
    EffectSpec("bearing_friction", "friction",
               (P("mur", "mm", 1e-3, (1.5, 5.0), "friction coefficient times pin radius of the crank bearing and "
                                                "rod eye (mu 0.1 x 15 mm = 1.5 mm)"),),
               "Merritt 1967 (load friction); Jelali & Kroll 2003 (bearing friction proportional to the joint load)",
               "torque on the crank -mur |F| tanh(omega / 0.02 rad/s), F = A_A P_A - A_B P_B the force the rod "
               "carries: Coulomb friction proportional to the joint load",
               accept=("friction",), places=("crank_torque", "piston_force"),
               why="a torque on the crank and a force on the piston are the same load seen through the lever"),
)}

ALL = {**OUT_OF_LIBRARY, **LIBRARY, **CHECKS, **UNLISTED}


def to_si(effects: dict) -> dict:
    """``{name: {param: value in its unit}}`` -> the same in SI (unknown names or params refused)."""
    out = {}
    for name, params in (effects or {}).items():
        if name not in ALL:
            raise KeyError(f"unknown effect {name!r}; known: {', '.join(ALL)}")
        spec = {p.name: p for p in ALL[name].params}
        for k in params:
            if k not in spec:
                raise KeyError(f"{name}: unknown parameter {k!r}; known: {', '.join(spec)}")
        out[name] = {k: float(v) * spec[k].si for k, v in params.items()}
    return out
