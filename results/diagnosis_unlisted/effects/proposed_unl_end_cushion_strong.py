"""proposed_unl_end_cushion_strong: a term proposed by ehas diagnose for /tmp/unl-work/unl_end_cushion_strong/campaign.

T_crank [N m] += c_w·omega   with c_w = -203.4 N m s/rad (95 % CI -213 to -193.7)
F_piston [N] += c_v·v + c_x2v·x^2 v   with c_v = 8.116e+04 N s/m (95 % CI 7.733e+04 to 8.499e+04); c_x2v = 3.818e+07 N s/m^3 (95 % CI 3.62e+07 to 4.016e+07)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.37 -> 2.38; fit 87.3 % -> 93.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlEndCushionStrong(Effect):
    name = "proposed_unl_end_cushion_strong"
    title = "proposed term (crank torque, piston force)"
    params = (
        Param("t_w", "N m s/rad", 203.376, (0.0, 4067.52),
              "viscous torque per rad/s (fitted: -203.4, 95 % CI -213 to -193.7)", typical=(101.688, 406.752)),
        Param("f_v", "N s/m", 81155.4, (0.0, 1.62311e+06),
              "viscous force per m/s (fitted: 8.116e+04, 95 % CI 7.733e+04 to 8.499e+04)", typical=(40577.7, 162311)),
        Param("f_x2v", "N s/m^3", 3.81786e+07, (0.0, 7.63571e+08),
              "viscous force that rises with position squared: per m^2 and per m/s (fitted: 3.818e+07, 95 % CI 3.62e+07 to 4.016e+07)", typical=(1.90893e+07, 7.63571e+07)),
    )
    main_param = "f_x2v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_w·omega with c_w = -203.4 N m s/rad (95 % CI -213 to -193.7); F_piston [N] += c_v·v + c_x2v·x^2 v with c_v = 8.116e+04 N s/m (95 % CI 7.733e+04 to 8.499e+04); c_x2v = 3.818e+07 N s/m^3 (95 % CI 3.62e+07 to 4.016e+07)'
    signature = 'the residual it was fitted to: v, x^2 v, omega'

    @staticmethod
    def crank_torque(omega, t_w):
        return -(t_w * omega)

    @staticmethod
    def piston_force(v, x, f_v, f_x2v):
        return (f_v * v) + (f_x2v * x ** 2 * v)
