"""proposed_unl_end_cushion_strong: a term proposed by ehas diagnose for /work/runs/unl/unl_end_cushion_strong/campaign.

T_crank [N m] += c_w·omega + c_th2w·theta^2 omega   with c_w = 8770 N m s/rad (95 % CI 8770 to 8770); c_th2w = -6362 N m s/rad^3 (95 % CI -6364 to -6361)
F_piston [N] += c_x2v·x^2 v + c_v·v   with c_x2v = -3.874e+08 N s/m^3 (95 % CI -3.878e+08 to -3.87e+08); c_v = -3.508e+06 N s/m (95 % CI -3.508e+06 to -3.508e+06)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.37 -> 1.98; fit 89.3 % -> 95.4 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlEndCushionStrong(Effect):
    name = "proposed_unl_end_cushion_strong"
    title = "proposed term (crank torque, piston force)"
    params = (
        Param("t_w", "N m s/rad", 8770.01, (0.0, 175400),
              "torque per rad/s of the crank rate, at the crank (fitted: 8770, 95 % CI 8770 to 8770)", typical=(4385, 17540)),
        Param("t_th2w", "N m s/rad^3", 6362.27, (0.0, 127245),
              "torque per rad^3/s of the crank angle squared times the crank rate, at the crank (fitted: -6362, 95 % CI -6364 to -6361)", typical=(3181.13, 12724.5)),
        Param("f_x2v", "N s/m^3", 3.87384e+08, (0.0, 7.74767e+09),
              "force per m^3/s of the piston position squared times the piston velocity, on the piston (fitted: -3.874e+08, 95 % CI -3.878e+08 to -3.87e+08)", typical=(1.93692e+08, 7.74767e+08)),
        Param("f_v", "N s/m", 3.50828e+06, (0.0, 7.01655e+07),
              "force per m/s of the piston velocity, on the piston (fitted: -3.508e+06, 95 % CI -3.508e+06 to -3.508e+06)", typical=(1.75414e+06, 7.01655e+06)),
    )
    main_param = "f_x2v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_w·omega + c_th2w·theta^2 omega with c_w = 8770 N m s/rad (95 % CI 8770 to 8770); c_th2w = -6362 N m s/rad^3 (95 % CI -6364 to -6361); F_piston [N] += c_x2v·x^2 v + c_v·v with c_x2v = -3.874e+08 N s/m^3 (95 % CI -3.878e+08 to -3.87e+08); c_v = -3.508e+06 N s/m (95 % CI -3.508e+06 to -3.508e+06)'
    signature = 'the residual it was fitted to: x^2 v, v, omega, theta^2 omega'

    @staticmethod
    def crank_torque(omega, theta, t_w, t_th2w):
        return (t_w * omega) + -(t_th2w * (theta ** 2) * omega)

    @staticmethod
    def piston_force(x, v, f_x2v, f_v):
        return -(f_x2v * (x ** 2) * v) + -(f_v * v)
