"""proposed_unl_end_cushion_strong: a term proposed by ehas diagnose for /tmp/s1/work_unl/unl_end_cushion_strong/campaign.

T_crank [N m] += c_w·omega   with c_w = -203.4 N m s/rad (95 % CI -213.1 to -193.7)
F_piston [N] += c_x2v·x^2 v + c_v·v   with c_x2v = 3.818e+07 N s/m^3 (95 % CI 3.621e+07 to 4.016e+07); c_v = 8.117e+04 N s/m (95 % CI 7.734e+04 to 8.499e+04)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.37 -> 2.38; fit 89.3 % -> 94.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlEndCushionStrong(Effect):
    name = "proposed_unl_end_cushion_strong"
    title = "proposed term (crank torque, piston force)"
    params = (
        Param("t_w", "N m s/rad", 203.406, (0.0, 4068.12),
              "viscous torque per rad/s (fitted: -203.4, 95 % CI -213.1 to -193.7)", typical=(101.703, 406.812)),
        Param("f_x2v", "N s/m^3", 3.81831e+07, (0.0, 7.63663e+08),
              "viscous force that rises with position squared: per m^2 and per m/s (fitted: 3.818e+07, 95 % CI 3.621e+07 to 4.016e+07)", typical=(1.90916e+07, 7.63663e+07)),
        Param("f_v", "N s/m", 81166.8, (0.0, 1.62334e+06),
              "viscous force per m/s (fitted: 8.117e+04, 95 % CI 7.734e+04 to 8.499e+04)", typical=(40583.4, 162334)),
    )
    main_param = "f_x2v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_w·omega with c_w = -203.4 N m s/rad (95 % CI -213.1 to -193.7); F_piston [N] += c_x2v·x^2 v + c_v·v with c_x2v = 3.818e+07 N s/m^3 (95 % CI 3.621e+07 to 4.016e+07); c_v = 8.117e+04 N s/m (95 % CI 7.734e+04 to 8.499e+04)'
    signature = 'the residual it was fitted to: x^2 v, omega, v'

    @staticmethod
    def crank_torque(omega, t_w):
        return -(t_w * omega)

    @staticmethod
    def piston_force(x, v, f_x2v, f_v):
        return (f_x2v * x ** 2 * v) + (f_v * v)
