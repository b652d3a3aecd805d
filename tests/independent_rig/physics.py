"""The rig's equations, written from docs/reference-model.md, plus the switchable effects of :mod:`.effects`.

State vector (SI): always these ten components (an effect that is off leaves its
states at rest), and after them the states of the unlisted classes that are on
(``lvdt_lag``: the reading x_r, m; ``hose_line``: the two valve-port pressures,
Pa), so that a campaign without them integrates exactly the ten it always did:

====  ========  ============================================================
 0    theta     crank angle, rad (0 at mid-stroke)
 1    omega     crank rate, rad/s
 2    qc        valve no-load flow at the rated drop, m^3/s
 3    qcd       its rate, m^3/s^2
 4    pa        chamber A pressure, Pa
 5    pb        chamber B pressure, Pa
 6    iv        valve coil current, mA (``current_lag`` only)
 7    xp        piston position, m (``load_compliance`` or ``backlash`` only)
 8    vp        piston velocity, m/s (``load_compliance`` or ``backlash`` only)
 9    z         LuGre bristle deflection, m (``lugre_friction`` only)
====  ========  ============================================================

The driver (:mod:`.simulate`) holds the amplifier's command constant over each
piece of a control period and integrates these rates with an adaptive
Runge-Kutta method; the end stops (spool, stroke, pressures within [0, Ps]) are
applied between pieces, as the reference model applies them between its steps.
Between pieces (up to 1 ms apart) a chamber pressure can run past 0 or Ps inside a
piece; with ``exact_bounds`` the pressure's rate is also zeroed outward at its bound
inside the right-hand side (the limit "held within [0, Ps]" tends to as the steps
shrink), which matters only where a run drives a chamber to a bound (a start from
rest without a fade-in): docs/independent-generator.md, "Start conditions".

Drawn blocks (:mod:`.grammar`: a (place, kind, magnitude) of hidden physics) act through :class:`Hooks`: a
signal hook where each signal of the model is computed (the amplifier's command, the coil current, each land's
flow, the supply and return pressures at the valve), an additive hook in each balance (the piston force, the
crank torque, each chamber's flow) and the structural hooks of a compliance (a body split off a mechanical
balance) and of a line volume (a pressure state in a hydraulic path).  Their states come after all the others.
Without blocks (``blocks=None``) none of this code runs: every campaign integrates as it always did.
"""
from __future__ import annotations

import math

import numpy as np

from .rig import BAR, LPM, Rig

N = 10
V_TANH = 1.0e-3  # m/s: smoothing of the friction sign (docs/reference-model.md, v_s)
P_ATM = 1.0e5  # Pa
KAPPA_AIR = 1.4  # polytropic exponent of the entrained air (adiabatic at these rates)
PISTON_MASS = 5.0  # kg: piston and rod when the load path is compliant (assumed, as the library's piston_mass default)
COMPLIANCE_DAMPING = 0.2  # damping ratio of the compliant load path (assumed)
LUGRE = {"ratio": 1.6, "vs": 5.0e-3, "sigma0": 1.0e6, "sigma1": 1.0e3, "sigma2": 300.0}  # assumed (Canudas 1995)
UNBALANCE_PHASE = math.pi / 3.0  # rad: the discs' centre of mass 60 deg from the bottom at mid-stroke
LINE_LOSS_REF_FLOW = 20.0 * LPM  # flow at which supply_line_loss's dp is given
JOINT_K, JOINT_C = 2.0e7, 3.0e3  # N/m, N s/m: contact of the joint with play (docs/reference-model.md, backlash)
# the unlisted classes (effects.UNLISTED); their figures are assumed, typical of the sources cited there
CUSHION_START = 0.6  # share of the half stroke beyond which an end cushion acts
SLEW_T = 2.0e-4  # s: the current driver's small-signal time constant under a slew limit
RIPPLE_HZ = 23.7  # Hz: once-per-revolution line of a 1422 rpm pump (one worn piston of nine)
HOSE_VOLUME = 50.0e-6  # m^3 of oil per hose when hose_line gives no V (1 m of 8 mm bore)
HOSE_REF_FLOW = 20.0 * LPM  # flow at which hose_line's dp is given
BEARING_W_TANH = 0.02  # rad/s: smoothing of the bearing friction's sign (1 mm/s at the 50 mm crank)
#: the crank's own inertia when a compliance splits the discs off the crank torque balance: the piston and rod
#: (PISTON_MASS) seen through the crank, kg m^2 per m^2 of crank radius (assumed: the crank arm's own is small)
CRANK_MASS = PISTON_MASS


def _root(z: float) -> float:
    """sign(z) sqrt(|z|)."""
    return math.sqrt(z) if z >= 0.0 else -math.sqrt(-z)


class Hooks:
    """The drawn blocks of one run, sorted by how each acts, with the indices of their states.

    A block (:class:`.grammar.Block`; read here only through its ``place``, ``mechanism``, ``n_states``,
    ``params`` and methods, so that this module imports nothing of the grammar) acts by one mechanism:

    * ``static``: a function of the signal (or, at a balance or a boundary pressure, an added term that is a
      function of the place's local quantities), evaluated where the model computes that place;
    * ``state``: a lag or a rate limit of a signal inside the integration, one state each;
    * ``structural``: a compliance (a body split off a mechanical balance) or a line volume (a pressure state in a
      hydraulic path);
    * ``tau``: a pure delay of the amplifier's held command (the exact switch instant, as the transport delay);
    * ``sequence``: play on the amplifier's held command, applied once per control period;
    * ``sampled``: a dynamic block on a logged reading, applied to the reading as the logger samples it.

    A block at zero magnitude (``block.null``) is left out: the hooks then run and change nothing.

    Parameters
    ----------
    blocks : list
        The blocks.
    first : int
        Index of the first free state.
    """

    def __init__(self, blocks, first: int):
        self.rhs, self.structural, self.reading, self.sampled = {}, {}, {}, {}
        self.sequence, self.tau, self.atol, self.pressure_states = [], 0.0, [], []
        n = first
        for b in blocks or ():
            if b.null:
                continue
            mech, place = b.mechanism, b.place.name
            if mech == "tau":
                self.tau += b.params["tau"]
            elif mech == "sequence":
                self.sequence.append(b.stepper(init=0.0))
            elif mech == "sampled":
                self.sampled.setdefault(place, []).append(b)
            elif mech == "static" and b.place.where == "sampled":
                self.reading.setdefault(place, []).append(b)
            else:
                k = n if b.n_states else None
                n += b.n_states
                self.atol += list(b.atol)
                if mech == "structural":
                    if place in self.structural:
                        raise ValueError(f"two structural blocks at {place}")
                    self.structural[place] = (b, k)
                    self.pressure_states += [k] if b.kind.name == "volume" else []
                else:
                    self.rhs.setdefault(place, []).append((b, k))
        self.n = n
        self.steppers = {p: [b.stepper() for b in bs] for p, bs in self.sampled.items()}

    def signal(self, place: str, u: float, y, dy) -> float:
        """The value a signal passes on after the blocks at ``place`` (static transforms, lags, rate limits)."""
        for b, k in self.rhs.get(place, ()):
            u = b.apply(u, y, dy, k)
        return u

    def term(self, place: str, loc: dict) -> float:
        """The sum of the terms the blocks add at a balance or a boundary, from its local quantities ``loc``."""
        return sum(b.term(loc) for b, _ in self.rhs.get(place, ()))

    def hold(self, u: float) -> float:
        """The amplifier's held command of this control period after the blocks on the held sequence (play)."""
        for s in self.sequence:
            u = s.step(u)
        return u

    def read(self, place: str, u: float) -> float:
        """A reading (SI) after its static blocks (a function of the value the transducer sees)."""
        for b in self.reading.get(place, ()):
            u = b.transform(u)
        return u

    def step_reading(self, place: str, u: float) -> float:
        """One sample of a reading through its dynamic blocks (this run's state)."""
        for s in self.steppers.get(place, ()):
            u = s.step(u)
        return u

    def read_series(self, place: str, u) -> np.ndarray:
        """A whole logged series (SI) through the blocks of its reading, static then dynamic, sample by sample."""
        out = np.array([self.read(place, float(v)) for v in u]) if place in self.reading else np.asarray(u, float)
        for b in self.sampled.get(place, ()):
            s = b.stepper()
            out = np.array([s.step(float(v)) for v in out])
        return out

    def reads(self, place: str) -> bool:
        """Whether any block acts at the reading ``place``."""
        return place in self.reading or place in self.sampled

    def volume(self, place: str):
        """(block, state index) of the line volume at a hydraulic place, or None."""
        s = self.structural.get(place)
        return s if s is not None and s[0].kind.name == "volume" else None


class RigModel:
    """Right-hand side of the rig with ``effects`` (SI values, :func:`.effects.to_si`).

    Parameters
    ----------
    rig : Rig
        Geometry and hydraulics.
    disc_sets : int
        Number of disc sets, 1-7.
    effects : dict
        ``{name: {param: SI value}}``.
    exact_bounds : bool
        Hold the chamber (and hose-port) pressures within [0, Ps] inside the right-hand side too (their rate
        zeroed outward at a bound), not only between the driver's pieces.
    blocks : list, optional
        Drawn blocks (:class:`.grammar.Block`) acting through :class:`Hooks`; None: no hook runs.
    """

    def __init__(self, rig: Rig, disc_sets: int, effects: dict | None = None, exact_bounds: bool = False,
                 blocks=None):
        self.rig = rig
        self.exact_bounds = exact_bounds
        self.inertia = rig.inertia_per_set * disc_sets
        e = dict(effects or {})
        self.e = e
        self.alpha = e.get("single_rod", {}).get("alpha", 1.0)
        self.a_a = rig.area
        self.a_b = rig.area * self.alpha
        self.p_t = e.get("return_pressure", {}).get("p_t", 0.0)
        self.eps = e.get("entrained_air", {}).get("eps", 0.0)
        self.k_c = e.get("load_compliance", {}).get("k", 0.0)
        self.c_c = 2.0 * COMPLIANCE_DAMPING * math.sqrt(self.k_c * PISTON_MASS) if self.k_c else 0.0
        self.play = e.get("backlash", {}).get("delta", 0.0)  # m: half the joint's total play
        self.two_body = bool(self.k_c or self.play)
        self.unbalance = e.get("crank_unbalance", {}).get("G", 0.0)
        self.lugre_fc = e.get("lugre_friction", {}).get("Fc", 0.0)
        self.dir_gain = e.get("valve_direction_gain", {}).get("g", 0.0)
        self.u0 = e.get("valve_underlap", {}).get("u0", 0.0)
        dp = e.get("supply_line_loss", {}).get("dp", 0.0)
        self.k_line = dp / LINE_LOSS_REF_FLOW ** 2  # Pa / (m^3/s)^2
        self.x0 = e.get("lvdt_offset", {}).get("x0", 0.0)
        self.lvdt_n = e.get("lvdt_nonlinearity", {}).get("n", 0.0)
        self.t_lag = e.get("current_lag", {}).get("T", 0.0)
        self.phi0 = e.get("crank_offset", {}).get("phi0", 0.0)
        self.drag = e.get("disc_drag", {}).get("c", 0.0)
        q100 = e.get("turbulent_leakage", {}).get("q100", 0.0)
        self.c_turb = q100 / math.sqrt(100.0 * BAR)
        self.fc = e.get("coulomb_friction", {}).get("Fc", 0.0)
        self.b = e.get("viscous_friction", {}).get("b", 0.0)
        self.tau = e.get("transport_delay", {}).get("tau", 0.0)
        self.i_bias = e.get("valve_null_bias", {}).get("i_bias", 0.0)
        self.c_leak = e.get("internal_leakage", {}).get("C_leak", 0.0)
        # unlisted classes
        self.bore_fw = e.get("bore_wear_friction", {}).get("Fw", 0.0)
        self.cushion = e.get("end_cushion", {}).get("ce", 0.0)
        self.gamma = e.get("land_flow_forces", {}).get("gamma", 0.0)
        self.slew = e.get("current_slew", {}).get("S", 0.0)
        self.lvdt_t = e.get("lvdt_lag", {}).get("T", 0.0)
        self.ripple = e.get("supply_ripple", {}).get("a", 0.0)
        self.hose_r = e.get("hose_line", {}).get("dp", 0.0) / HOSE_REF_FLOW  # Pa s/m^3
        self.hose_v = e.get("hose_line", {}).get("V", HOSE_VOLUME)  # m^3
        self.mur = e.get("bearing_friction", {}).get("mur", 0.0)
        # states beyond the ten, only when their effect is on
        self.n = N
        self.i_xr = self.i_hose = None
        if self.lvdt_t:
            self.i_xr, self.n = self.n, self.n + 1
        if self.hose_r:
            self.i_hose, self.n = self.n, self.n + 2
        self.hooks = None
        self.crank_split = None
        if blocks is not None:
            self._hook(blocks)

    def _hook(self, blocks) -> None:
        """Sort the drawn blocks into :class:`Hooks` and wire the structural ones into the model."""
        self.hooks = h = Hooks(blocks, self.n)
        self.n = h.n
        self.tau += h.tau
        for place in ("chamber_a", "chamber_b"):
            if h.volume(place) and self.hose_r:
                raise ValueError(f"a line volume at {place} and hose_line together are not modelled")
        comp = h.structural.get("piston_force")
        if comp is not None:  # the generator's own split of piston and crank (states 7, 8), the block's spring
            if self.two_body:
                raise ValueError("a compliance at the piston force and load_compliance/backlash together")
            self.k_c = comp[0].params["k"]
            self.c_c = comp[0].params["c"]
            self.two_body = True
        self.crank_split = h.structural.get("crank_torque")

    def extra_atol(self) -> list:
        """Absolute tolerances of the states beyond the ten (reading m, port pressures Pa, the blocks' own)."""
        return ([1e-11] * (self.i_xr is not None) + [1e-2, 1e-2] * (self.i_hose is not None)
                + (self.hooks.atol if self.hooks is not None else []))

    def valve_states(self) -> list:
        """Indices of the states the flow bench integrates: the spool, the coil, and the blocks' states on the
        command and the coil current."""
        h = self.hooks
        extra = []
        for place in ("command_current", "coil_current"):
            for b, k in (h.rhs.get(place, ()) if h is not None else ()):
                extra += list(range(k, k + b.n_states)) if k is not None else []
        return [2, 3, 6] + extra

    def hold(self, i_cmd: float) -> float:
        """The amplifier's command held over a control period (mA): the controller's, after play on it."""
        return self.hooks.hold(i_cmd) if self.hooks is not None else i_cmd

    def supply(self, t: float) -> float:
        """Supply pressure at the pump at time t, Pa (with the pump's ripple)."""
        if not self.ripple:
            return self.rig.supply
        return self.rig.supply + self.ripple * math.sin(2.0 * math.pi * RIPPLE_HZ * t)

    def land(self, d: float) -> float:
        """A land's flow per unit opening (as no-load flow) for its drop d, -: sign(d) |d / (dp_n/2)|^(1/2 - gamma)."""
        z = d / (0.5 * self.rig.rated_drop)
        if not self.gamma:
            return _root(z)
        return math.copysign(abs(z) ** (0.5 - self.gamma), z)

    # -- pieces ---------------------------------------------------------
    def crank_x(self, theta: float) -> float:
        """Rod-joint position along the piston axis for crank angle theta, m (0 at mid-stroke)."""
        r = self.rig.radius
        return r * (math.sin(theta + self.phi0) - math.sin(self.phi0))

    def piston(self, y) -> tuple:
        """(x, v) of the piston, m and m/s."""
        if self.two_body:
            return y[7], y[8]
        r = self.rig.radius
        return self.crank_x(y[0]), r * math.cos(y[0] + self.phi0) * y[1]

    def lvdt_reading(self, y) -> float:
        """The position the LVDT shows, m (its effects and the static blocks at its reading; before noise)."""
        x = y[self.i_xr] if self.i_xr is not None else self.piston(y)[0]
        h = self.rig.half_stroke
        xr = x + self.x0 + self.lvdt_n * h * (x / h) ** 3
        return self.hooks.read("position_reading", xr) if self.hooks is not None else xr

    def angle_of(self, xr: float) -> float:
        """The logger's asin(x_read / r), deg."""
        return math.degrees(math.asin(max(-1.0, min(1.0, xr / self.rig.radius))))

    def lvdt_angle_deg(self, y) -> float:
        """The angle the LVDT shows, asin(x_read / r), deg (before noise and ADC)."""
        return self.angle_of(self.lvdt_reading(y))

    def valve_input(self, i_cmd: float) -> float:
        """Amplifier clip, then the null bias: the current that drives the valve (before a coil lag), mA."""
        i = max(-self.rig.i_max, min(self.rig.i_max, i_cmd))
        return i + self.i_bias

    def beta(self, p: float) -> float:
        """Effective bulk modulus at pressure p, Pa."""
        beta = self.rig.beta
        if not self.eps:
            return beta
        p = max(p, P_ATM)
        va = self.eps * (P_ATM / p) ** (1.0 / KAPPA_AIR)
        a = va / (1.0 + va)
        return 1.0 / ((1.0 - a) / beta + a / (KAPPA_AIR * p))

    def supply_at_valve(self, qc: float, p_in: float, t: float = 0.0) -> float:
        """Supply pressure at the valve, Pa: Ps less the line loss k Q_s^2, Q_s through the inflow land."""
        ps = self.supply(t)
        if not self.k_line:
            return ps
        half = 0.5 * self.rig.rated_drop
        # Q_s^2 = qc^2 (ps_v - p_in) / half and ps_v = ps - k Q_s^2: solved for ps_v - p_in
        s = (ps - p_in) / (1.0 + self.k_line * qc * qc / half)
        return p_in + s

    def land_flows(self, qc: float, pa: float, pb: float, t: float = 0.0) -> tuple:
        """(Q into A, Q into B), m^3/s: four metering lands, each by the root of its own drop (:meth:`land`);
        pa, pb the pressures at the valve's ports."""
        u0, pt = self.u0, self.p_t
        p_in = pa if qc >= 0.0 else pb
        ps = self.supply_at_valve(qc, p_in, t)
        a_pa = max(u0 + qc, 0.0)  # supply -> A land opening (as no-load flow)
        a_at = max(u0 - qc, 0.0)  # A -> tank
        a_pb = a_at  # supply -> B opens with negative q_c
        a_bt = a_pa  # B -> tank opens with positive q_c
        land = self.land
        qa = a_pa * land(ps - pa) - a_at * land(pa - pt)
        qb = a_pb * land(ps - pb) - a_bt * land(pb - pt)
        return qa, qb

    # -- the right-hand side -------------------------------------------
    def rates(self, y, i_cmd: float, t: float = 0.0) -> list:
        """dy/dt at state y and time t (s) with the amplifier's command i_cmd (mA)."""
        rig = self.rig
        theta, omega, qc, qcd, pa, pb, iv, xp, vp, z = y[:N]
        dy = [0.0] * self.n
        H = self.hooks
        # command path -> valve
        i_in = self.valve_input(H.signal("command_current", i_cmd, y, dy) if H is not None else i_cmd)
        if self.t_lag or self.slew:
            rate = (i_in - iv) / (self.t_lag or SLEW_T)
            dy[6] = self.slew * math.tanh(rate / self.slew) if self.slew else rate
            i_v = iv
        else:
            i_v = i_in
        if H is not None:
            i_v = H.signal("coil_current", i_v, y, dy)
        sgn = 1.0 if i_v > 0.0 else (-1.0 if i_v < 0.0 else 0.0)
        target = rig.K * i_v * (1.0 + self.dir_gain * sgn)
        dy[2] = qcd
        dy[3] = rig.wn * rig.wn * (target - qc) - 2.0 * rig.zeta * rig.wn * qcd
        q_stop = rig.K * rig.i_max
        if (qc >= q_stop and qcd >= 0.0) or (qc <= -q_stop and qcd <= 0.0):
            dy[2] = 0.0
            dy[3] = min(dy[3], 0.0) if qc > 0 else max(dy[3], 0.0)
        # chambers
        x, v = self.piston(y)
        if H is not None:
            qa, qb = self._hooked_chamber_flows(y, dy, qc, pa, pb, t)
        elif self.i_hose is not None:  # valve ports, then the hoses into the chambers
            k = self.i_hose
            pva, pvb = y[k], y[k + 1]
            qva, qvb = self.land_flows(qc, pva, pvb, t)
            qa, qb = (pva - pa) / self.hose_r, (pvb - pb) / self.hose_r
            dy[k] = self.beta(pva) / self.hose_v * (qva - qa)
            dy[k + 1] = self.beta(pvb) / self.hose_v * (qvb - qb)
        else:
            qa, qb = self.land_flows(qc, pa, pb, t)
        if self.i_xr is not None:
            dy[self.i_xr] = (x - y[self.i_xr]) / self.lvdt_t
        dp = pa - pb
        q_leak = self.c_leak * dp + self.c_turb * _root(dp)
        h, vd = rig.half_stroke, rig.dead_volume
        va = self.a_a * (h + x) + vd
        vb = self.a_b * (h - x) + vd
        if H is not None:  # the flows the blocks add to each chamber's balance
            qa += H.term("chamber_a", {"p": pa, "dp": pa - pb, "v": v})
            qb += H.term("chamber_b", {"p": pb, "dp": pb - pa, "v": -v})
        dy[4] = self.beta(pa) / va * (qa - self.a_a * v - q_leak)
        dy[5] = self.beta(pb) / vb * (qb + self.a_b * v + q_leak)
        # forces on the piston (+x toward chamber B)
        f = self.a_a * pa - self.a_b * pb
        if self.fc:
            f -= self.fc * math.tanh(v / V_TANH)
        if self.b:
            f -= self.b * v
        if self.lugre_fc:
            fs = LUGRE["ratio"] * self.lugre_fc
            g = self.lugre_fc + (fs - self.lugre_fc) * math.exp(-(v / LUGRE["vs"]) ** 2)
            zd = v - LUGRE["sigma0"] * abs(v) * z / g
            dy[9] = zd
            f -= LUGRE["sigma0"] * z + LUGRE["sigma1"] * zd + LUGRE["sigma2"] * v
        if self.bore_fw:
            f -= self.bore_fw * (x / rig.half_stroke) ** 2 * math.tanh(v / V_TANH)
        if self.cushion:
            s = max(0.0, (abs(x) / rig.half_stroke - CUSHION_START) / (1.0 - CUSHION_START))
            f -= self.cushion * v * s * s
        if H is not None:
            f += H.term("piston_force", {"v": v, "x": x, "pL": pa - pb})
        # torque on the crank
        torque = 0.0
        if self.unbalance:
            torque -= self.unbalance * math.sin(theta + UNBALANCE_PHASE)
        if self.drag:
            torque -= self.drag * omega * abs(omega)
        if H is not None:
            torque += H.term("crank_torque", {"w": omega, "th": theta})
        lever = rig.radius * math.cos(theta + self.phi0)
        dy[0] = omega
        if self.two_body:
            xc = self.crank_x(theta)
            gap, gap_rate = xp - xc, vp - lever * omega
            if self.play:  # contact only beyond the play
                f_rod = (JOINT_K * (gap - self.play) + JOINT_C * gap_rate if gap > self.play else
                         JOINT_K * (gap + self.play) + JOINT_C * gap_rate if gap < -self.play else 0.0)
            else:
                f_rod = self.k_c * gap + self.c_c * gap_rate
            if self.mur:
                torque -= self.mur * abs(f_rod) * math.tanh(omega / BEARING_W_TANH)
            dy[7] = vp
            dy[8] = (f - f_rod) / PISTON_MASS
            drive = f_rod * lever
            dy[1] = (drive + torque) / self.inertia
        else:
            if self.mur:
                torque -= self.mur * abs(f) * math.tanh(omega / BEARING_W_TANH)
            drive = f * lever
            dy[1] = (drive + torque) / self.inertia
        if self.crank_split is not None:
            self._split_crank(y, dy, drive, torque)
        if self.exact_bounds:
            top = rig.supply + self.ripple
            for j in self._pressure_states():
                if (y[j] <= 0.0 and dy[j] < 0.0) or (y[j] >= top and dy[j] > 0.0):
                    dy[j] = 0.0
            self._held_at_stroke_end(y, dy)
        return dy

    def _held_at_stroke_end(self, y, dy) -> None:
        """At a stroke end, not moving inward and pushed outward: the stop's reaction holds the piston there (its
        velocity and acceleration outward are zero), in place.  With :meth:`stroke_end` as the driver's event the
        impact is resolved at its instant, not at the next piece's boundary (``exact_bounds``)."""
        x, v = self.piston(y)
        h = self.rig.half_stroke
        if abs(x) < h * (1.0 - 1e-12):
            return
        out = math.copysign(1.0, x)
        if self.two_body:
            if v * out <= 0.0 and dy[8] * out > 0.0:
                dy[7] = min(dy[7] * out, 0.0) * out
                dy[8] = 0.0
            return
        lever = self.rig.radius * math.cos(y[0] + self.phi0)  # dx/dtheta
        if v * out <= 0.0 and dy[1] * lever * out > 0.0:
            dy[0] = dy[0] if dy[0] * lever * out < 0.0 else 0.0
            dy[1] = 0.0

    def stroke_end(self, y) -> float:
        """How far the piston is inside its stroke, m, less a hair (negative only past an end: the driver's event
        with ``exact_bounds``; a piston held at the end is not an impact)."""
        h = self.rig.half_stroke
        return h * (1.0 + 1e-12) - abs(self.piston(y)[0])

    def _pressure_states(self) -> tuple:
        """Indices of every pressure state: the chambers, hose_line's ports, the blocks' line volumes."""
        return ((4, 5) + ((self.i_hose, self.i_hose + 1) if self.i_hose is not None else ())
                + (tuple(self.hooks.pressure_states) if self.hooks is not None else ()))

    def _split_crank(self, y, dy, drive: float, torque: float) -> None:
        """A compliance at the crank torque balance: the crank (the piston and rod seen through it,
        :data:`CRANK_MASS` r^2) takes the rod's torque ``drive``; the discs (their inertia) take ``torque`` (the
        load's own terms) and the torsion spring k_t (theta - theta_d) + c_t (omega - omega_d) between the two."""
        b, k = self.crank_split
        spring = b.params["k"] * (y[0] - y[k]) + b.params["c"] * (y[1] - y[k + 1])
        dy[1] = (drive - spring) / (CRANK_MASS * self.rig.radius ** 2)
        dy[k] = y[k + 1]
        dy[k + 1] = (spring + torque) / self.inertia

    def _boundaries(self, y, dy, qc: float, pa: float, pb: float, t: float) -> tuple:
        """(supply, return) pressures at the valve's lands with the blocks at both boundaries, Pa; the line volumes'
        rates written into dy.  pa, pb: the pressures at the valve's ports."""
        H = self.hooks
        p_in = pa if qc >= 0.0 else pb
        loc = {"q": abs(qc)}
        ps = self.supply_at_valve(qc, p_in, t) + H.term("supply", loc)
        pt = self.p_t + H.term("return", loc)
        u0, land = self.u0, self.land
        a_pa, a_at = max(u0 + qc, 0.0), max(u0 - qc, 0.0)
        line = H.volume("supply")
        if line is not None:  # the supply line's volume behind its resistance, fed from the pump side ps
            b, k = line
            pv = y[k]
            q_s = a_pa * land(pv - pa) + a_at * land(pv - pb)
            dy[k] = self.beta(pv) / b.params["V"] * ((ps - pv) / b.params["R"] - q_s)
            ps = pv
        line = H.volume("return")
        if line is not None:  # the return line's volume, drained to the tank pt through its resistance
            b, k = line
            pv = y[k]
            q_r = a_at * land(pa - pv) + a_pa * land(pb - pv)
            dy[k] = self.beta(pv) / b.params["V"] * (q_r - (pv - pt) / b.params["R"])
            pt = pv
        return ps, pt

    def _hooked_land_flows(self, y, dy, qc: float, pa: float, pb: float, t: float) -> tuple:
        """(Q out of port A, Q out of port B), m^3/s: :meth:`land_flows` with the blocks at the boundaries and at
        each land's flow; pa, pb the pressures at the valve's ports."""
        ps, pt = self._boundaries(y, dy, qc, pa, pb, t)
        u0, land = self.u0, self.land
        a_pa = max(u0 + qc, 0.0)  # supply -> A land opening (as no-load flow)
        a_at = max(u0 - qc, 0.0)  # A -> tank
        a_pb = a_at  # supply -> B opens with negative q_c
        a_bt = a_pa  # B -> tank opens with positive q_c
        qa = a_pa * land(ps - pa) - a_at * land(pa - pt)
        qb = a_pb * land(ps - pb) - a_bt * land(pb - pt)
        H = self.hooks
        return H.signal("land_a", qa, y, dy), H.signal("land_b", qb, y, dy)

    def _ports(self, y, pa: float, pb: float) -> tuple:
        """Pressures at the valve's ports A and B: hose_line's port states, a block's line volume, or the
        chambers'."""
        if self.i_hose is not None:
            pa, pb = y[self.i_hose], y[self.i_hose + 1]
        H = self.hooks
        if H is not None:
            va, vb = H.volume("chamber_a"), H.volume("chamber_b")
            pa = y[va[1]] if va is not None else pa
            pb = y[vb[1]] if vb is not None else pb
        return pa, pb

    def _hooked_chamber_flows(self, y, dy, qc: float, pa: float, pb: float, t: float) -> tuple:
        """(Q into chamber A, Q into chamber B), m^3/s, with the blocks: the lands feed the ports, each port's line
        (hose_line's, or a block's volume behind its resistance) feeds its chamber."""
        pva, pvb = self._ports(y, pa, pb)
        qva, qvb = self._hooked_land_flows(y, dy, qc, pva, pvb, t)
        qa, qb = qva, qvb
        if self.i_hose is not None:
            k = self.i_hose
            qa, qb = (pva - pa) / self.hose_r, (pvb - pb) / self.hose_r
            dy[k] = self.beta(pva) / self.hose_v * (qva - qa)
            dy[k + 1] = self.beta(pvb) / self.hose_v * (qvb - qb)
        for place, pv, qv, pc in (("chamber_a", pva, qva, pa), ("chamber_b", pvb, qvb, pb)):
            line = self.hooks.volume(place)
            if line is not None:
                b, k = line
                q = (pv - pc) / b.params["R"]
                dy[k] = self.beta(pv) / b.params["V"] * (qv - q)
                qa, qb = (q, qb) if place == "chamber_a" else (qa, q)
        return qa, qb

    def initial_state(self) -> list:
        """At rest at mid-stroke, both chambers at Ps/2 (docs/reference-model.md §4); the blocks' states at rest."""
        y = [0.0] * self.n
        y[4] = y[5] = 0.5 * self.rig.supply
        if self.i_hose is not None:
            y[self.i_hose] = y[self.i_hose + 1] = 0.5 * self.rig.supply
        if self.hooks is not None:
            for b, k in [*(x for bs in self.hooks.rhs.values() for x in bs), *self.hooks.structural.values()]:
                if k is not None:
                    y[k:k + b.n_states] = b.rest(self.rig)
        return y

    def rest_at_angle(self, y) -> None:
        """Bring the blocks' states to rest with the crank where ``y`` puts it (the discs of a compliant crank at the
        crank's angle); in place."""
        if self.crank_split is not None:
            y[self.crank_split[1]] = y[0]

    def apply_stops(self, y) -> bool:
        """Spool end stops, pressures within [0, Ps], stroke ends; in place. True when a stroke end was touched."""
        rig = self.rig
        q_stop = rig.K * rig.i_max
        if abs(y[2]) > q_stop:
            y[2] = math.copysign(q_stop, y[2])
            if y[3] * y[2] > 0.0:
                y[3] = 0.0
        top = rig.supply + self.ripple
        for j in self._pressure_states():
            y[j] = min(max(y[j], 0.0), top)
        x, _ = self.piston(y)
        if abs(x) > rig.half_stroke:
            self.impact(y)
            return True
        return False

    def impact(self, y) -> None:
        """The piston at the stroke end nearest it, its outward velocity gone (an inelastic stop); in place."""
        rig = self.rig
        lim = math.copysign(rig.half_stroke, self.piston(y)[0])
        if self.two_body:
            y[7] = lim
            y[8] = 0.0 if y[8] * lim > 0 else y[8]
        else:
            y[0] = math.asin(lim / rig.radius + math.sin(self.phi0)) - self.phi0
            y[1] = 0.0 if y[1] * lim > 0 else y[1]

    def outputs(self, y, t: float = 0.0) -> dict:
        """What the rig's transducers see (before noise): flow into A at the valve's port (LPM), chamber
        pressures (bar)."""
        if self.hooks is not None:
            qa, _ = self._hooked_land_flows(y, [0.0] * self.n, y[2], *self._ports(y, y[4], y[5]), t)
        else:
            ports = (y[self.i_hose], y[self.i_hose + 1]) if self.i_hose is not None else (y[4], y[5])
            qa, _ = self.land_flows(y[2], *ports, t)
        return {"flow_lpm": qa / LPM, "p_a_bar": y[4] / BAR, "p_b_bar": y[5] / BAR}
