"""proposed_unl_bearing_friction_strong: a term proposed by ehas diagnose for /tmp/unl-work/unl_bearing_friction_strong/campaign.

T_crank [N m] += c_jsw·|p_A - p_B| r |cos theta| tanh(r omega / v_tanh)   with c_jsw = -7.554e-05 m^3 (95 % CI -7.83e-05 to -7.279e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.68 -> 1.19; fit 91.5 % -> 96.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlBearingFrictionStrong(Effect):
    name = "proposed_unl_bearing_friction_strong"
    title = "proposed term (crank torque)"
    params = (
        Param("t_jsw", "m^3", 7.55441e-05, (0.0, 0.00151088),
              "dry torque that rises with the joint's load: per Pa of |p_L| r |cos theta|, times sign(omega) (a joint's friction, Pa x m^2 x m) (fitted: -7.554e-05, 95 % CI -7.83e-05 to -7.279e-05)", typical=(3.7772e-05, 0.000151088)),
    )
    main_param = "t_jsw"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_jsw·|p_A - p_B| r |cos theta| tanh(r omega / v_tanh) with c_jsw = -7.554e-05 m^3 (95 % CI -7.83e-05 to -7.279e-05)'
    signature = 'the residual it was fitted to: |p_A - p_B| r |cos theta| tanh(r omega / v_tanh)'

    @staticmethod
    def crank_torque(theta, omega, pa, pb, radius, v_tanh, t_jsw):
        return -(t_jsw * abs(pa - pb) * radius * abs(math.cos(theta)) * math.tanh(radius * omega / v_tanh))
