"""proposed_unl_bearing_friction_strong: a term proposed by ehas diagnose for /work/runs/unl/unl_bearing_friction_strong/campaign.

F_piston [N] += c_plsv·|p_A - p_B| tanh(v / v_tanh)   with c_plsv = -7.553e-05 m^2 (95 % CI -7.799e-05 to -7.308e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.94 -> 1.15; fit 93.0 % -> 96.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlBearingFrictionStrong(Effect):
    name = "proposed_unl_bearing_friction_strong"
    title = "proposed term (piston force)"
    params = (
        Param("f_plsv", "m^2", 7.55349e-05, (0.0, 0.0015107),
              "force per N/m^2 of the load pressure times the sign of the piston velocity, on the piston (fitted: -7.553e-05, 95 % CI -7.799e-05 to -7.308e-05)", typical=(3.77675e-05, 0.00015107)),
    )
    main_param = "f_plsv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_plsv·|p_A - p_B| tanh(v / v_tanh) with c_plsv = -7.553e-05 m^2 (95 % CI -7.799e-05 to -7.308e-05)'
    signature = 'the residual it was fitted to: |p_A - p_B| tanh(v / v_tanh)'

    @staticmethod
    def piston_force(pa, pb, v, v_tanh, f_plsv):
        return -(f_plsv * (abs(pa - pb)) * (math.tanh(v / v_tanh)))
