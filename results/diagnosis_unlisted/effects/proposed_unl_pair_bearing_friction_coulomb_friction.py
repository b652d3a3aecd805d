"""proposed_unl_pair_bearing_friction_coulomb_friction: a term proposed by ehas diagnose for /tmp/unl-work/unl_pair_bearing_friction+coulomb_friction/campaign.

T_crank [N m] += c_sw·tanh(r omega / v_tanh)   with c_sw = -13.44 N m (95 % CI -13.7 to -13.17)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.98 -> 1.45; fit 80.6 % -> 96.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairBearingFrictionCoulombFriction(Effect):
    name = "proposed_unl_pair_bearing_friction_coulomb_friction"
    title = "proposed term (crank torque)"
    params = (
        Param("t_sw", "N m", 13.4384, (0.0, 268.769),
              "dry torque times sign(omega) (fitted: -13.44, 95 % CI -13.7 to -13.17)", typical=(6.71921, 26.8769)),
    )
    main_param = "t_sw"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_sw·tanh(r omega / v_tanh) with c_sw = -13.44 N m (95 % CI -13.7 to -13.17)'
    signature = 'the residual it was fitted to: tanh(r omega / v_tanh)'

    @staticmethod
    def crank_torque(omega, radius, v_tanh, t_sw):
        return -(t_sw * math.tanh(radius * omega / v_tanh))
