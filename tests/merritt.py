"""Merritt's hand-derived linear model of the rig: the oracle the numerical linearisation is held to.

Valve (identified 2nd order) x flow gain at the operating point x actuator / crank /
inertia with chamber compliance::

    q_c'' = wn^2 (K i - q_c) - 2 zeta wn q_c'                 (valve, K in m^3/s per mA)
    C P_L' = Kq q_c - Kce P_L - a omega                       (chambers, C = 1/(beta (1/V_A + 1/V_B)))
    I_eff omega' = a P_L - B omega                            (crank and discs)

* ``Kq = sqrt((Ps - P_L0) / dp_n)``; ``Kc = |q_c0| / (2 sqrt(dp_n (Ps - P_L0)))``;
* ``Kce = Kc + C_leak + C_ext / 2``; ``a = A r cos(theta0)``;
* ``I_eff = I + m_piston (r cos theta0)^2``, ``B = b (r cos theta0)^2``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np

BAR = 1e5
LPM = 1e-3 / 60


def _eff(s: dict, name: str, param: str) -> float:
    return s.get(f"{name}.{param}", 0.0) if s.get(f"{name}.on") else 0.0


@dataclass
class Merritt:
    K: float
    wn: float
    zeta: float
    Kq: float
    Kc: float
    Kce: float
    C: float
    a: float
    I: float
    B: float

    @classmethod
    def of(cls, plant, theta_deg: float = 0.0, load_bar: float = 0.0, flow_lpm: float = 0.0) -> "Merritt":
        s = plant.slots()
        th = math.radians(theta_deg)
        load = load_bar * BAR
        r, A = s["radius"], s["area"]
        c = math.cos(th)
        x0 = r * math.sin(th)
        va = A * s["half_stroke"] + s["dead_volume"] + A * x0
        vb = A * s["half_stroke"] + s["dead_volume"] - A * x0
        kc = abs(flow_lpm) * LPM / (2.0 * math.sqrt(s["rated_drop"] * (s["supply"] - abs(load))))
        return cls(K=s["K"], wn=s["wn"], zeta=s["zeta"], Kq=math.sqrt((s["supply"] - abs(load)) / s["rated_drop"]),
                   Kc=kc, Kce=kc + _eff(s, "internal_leakage", "C_leak") + 0.5 * _eff(s, "external_leakage", "C_ext"),
                   C=1.0 / (s["beta"] * (1.0 / va + 1.0 / vb)), a=A * r * c,
                   I=s["inertia"] + _eff(s, "piston_mass", "m") * (r * c) ** 2,
                   B=_eff(s, "viscous_friction", "b") * (r * c) ** 2)

    @property
    def hydraulic_wn(self) -> float:
        return math.sqrt((self.a ** 2 + self.Kce * self.B) / (self.C * self.I))

    @property
    def velocity_gain(self) -> float:
        """deg/s per mA at steady state (P_L' = omega' = 0)."""
        return math.degrees(self.K * self.Kq * self.a / (self.a ** 2 + self.Kce * self.B))

    def tf(self, Kdp: float = 0.0, dp_hp: float = 0.0) -> control.TransferFunction:
        """theta (deg) / u (mA) with the load-pressure feedback i = u - Kdp H P_L closed, no delay."""
        s = control.tf("s")
        valve = self.K * self.wn ** 2 / (s ** 2 + 2 * self.zeta * self.wn * s + self.wn ** 2)
        m = (self.C * s + self.Kce) * (self.I * s + self.B) + self.a ** 2
        pl = self.Kq * (self.I * s + self.B) / m / BAR  # P_L (bar) per q_c
        th = self.Kq * self.a / (s * m)  # theta (rad) per q_c
        h = s / (s + dp_hp) if dp_hp > 0 else 1
        loop = valve / (1 + Kdp * h * valve * pl) if Kdp else valve
        return math.degrees(1.0) * loop * th

    def freqresp(self, w, Kdp: float = 0.0, dp_hp: float = 0.0) -> np.ndarray:
        return np.array([complex(self.tf(Kdp, dp_hp)(1j * wk)) for wk in w])
