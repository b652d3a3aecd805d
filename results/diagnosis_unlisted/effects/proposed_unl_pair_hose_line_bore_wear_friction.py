"""proposed_unl_pair_hose_line_bore_wear_friction: a term proposed by ehas diagnose for /tmp/unl-work/unl_pair_hose_line+bore_wear_friction/campaign.

T_crank [N m] += c_th2sw·theta^2 tanh(r omega / v_tanh)   with c_th2sw = -30.79 N m/rad^2 (95 % CI -31.29 to -30.29)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 14.2 -> 5.41; fit 77.8 % -> 90.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairHoseLineBoreWearFriction(Effect):
    name = "proposed_unl_pair_hose_line_bore_wear_friction"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th2sw", "N m/rad^2", 30.7901, (0.0, 615.803),
              "dry torque that rises with angle squared: per rad^2, times sign(omega) (fitted: -30.79, 95 % CI -31.29 to -30.29)", typical=(15.3951, 61.5803)),
    )
    main_param = "t_th2sw"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th2sw·theta^2 tanh(r omega / v_tanh) with c_th2sw = -30.79 N m/rad^2 (95 % CI -31.29 to -30.29)'
    signature = 'the residual it was fitted to: theta^2 tanh(r omega / v_tanh)'

    @staticmethod
    def crank_torque(theta, omega, radius, v_tanh, t_th2sw):
        return -(t_th2sw * theta ** 2 * math.tanh(radius * omega / v_tanh))
