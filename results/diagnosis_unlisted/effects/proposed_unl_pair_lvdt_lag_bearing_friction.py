"""proposed_unl_pair_lvdt_lag_bearing_friction: a term proposed by ehas diagnose for /tmp/ehas_unlisted_L/unl_pair_lvdt_lag+bearing_friction/campaign.

T_crank [N m] += c_jsw·|p_A - p_B| r |cos theta| tanh(r omega / v_tanh)   with c_jsw = -2.236e-05 m^3 (95 % CI -2.34e-05 to -2.132e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.09 -> 1.52; fit 95.3 % -> 96.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairLvdtLagBearingFriction(Effect):
    name = "proposed_unl_pair_lvdt_lag_bearing_friction"
    title = "proposed term (crank torque)"
    params = (
        Param("t_jsw", "m^3", 2.23619e-05, (0.0, 0.000447238),
              "dry torque that rises with the joint's load: per Pa of |p_L| r |cos theta|, times sign(omega) (a joint's friction, Pa x m^2 x m) (fitted: -2.236e-05, 95 % CI -2.34e-05 to -2.132e-05)", typical=(1.11809e-05, 4.47238e-05)),
    )
    main_param = "t_jsw"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_jsw·|p_A - p_B| r |cos theta| tanh(r omega / v_tanh) with c_jsw = -2.236e-05 m^3 (95 % CI -2.34e-05 to -2.132e-05)'
    signature = 'the residual it was fitted to: |p_A - p_B| r |cos theta| tanh(r omega / v_tanh)'

    @staticmethod
    def crank_torque(theta, omega, pa, pb, radius, v_tanh, t_jsw):
        return -(t_jsw * abs(pa - pb) * radius * abs(math.cos(theta)) * math.tanh(radius * omega / v_tanh))
