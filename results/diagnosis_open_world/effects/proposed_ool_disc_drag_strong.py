"""proposed_ool_disc_drag_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_disc_drag_strong/campaign.

T_crank [N m] += c_w·omega   with c_w = -30.27 N m s/rad (95 % CI -31.33 to -29.2)
F_piston [N] += c_vv·v |v| + c_v·v   with c_vv = -2.522e+04 N s^2/m^2 (95 % CI -2.533e+04 to -2.511e+04); c_v = 1.475e+04 N s/m (95 % CI 1.314e+04 to 1.635e+04)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 22.3 -> 2.47; fit 79.1 % -> 96.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolDiscDragStrong(Effect):
    name = "proposed_ool_disc_drag_strong"
    title = "proposed term (crank torque, piston force)"
    params = (
        Param("t_w", "N m s/rad", 30.2675, (0.0, 605.35),
              "viscous torque per rad/s (fitted: -30.27, 95 % CI -31.33 to -29.2)", typical=(15.1337, 60.535)),
        Param("f_vv", "N s^2/m^2", 25220.2, (0.0, 504404),
              "quadratic damping: force per (m/s)^2, signed (fitted: -2.522e+04, 95 % CI -2.533e+04 to -2.511e+04)", typical=(12610.1, 50440.4)),
        Param("f_v", "N s/m", 14747.4, (0.0, 294948),
              "viscous force per m/s (fitted: 1.475e+04, 95 % CI 1.314e+04 to 1.635e+04)", typical=(7373.69, 29494.8)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_w·omega with c_w = -30.27 N m s/rad (95 % CI -31.33 to -29.2); F_piston [N] += c_vv·v |v| + c_v·v with c_vv = -2.522e+04 N s^2/m^2 (95 % CI -2.533e+04 to -2.511e+04); c_v = 1.475e+04 N s/m (95 % CI 1.314e+04 to 1.635e+04)'
    signature = 'the residual it was fitted to: v |v|, v, omega'

    @staticmethod
    def crank_torque(omega, t_w):
        return -(t_w * omega)

    @staticmethod
    def piston_force(v, f_vv, f_v):
        return -(f_vv * v * abs(v)) + (f_v * v)
