"""proposed_unl_bore_wear_friction_mild: a term proposed by ehas diagnose for /work/runs/unl/unl_bore_wear_friction_mild/campaign.

F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh)   with c_x2sv = -3.274e+05 N/m^2 (95 % CI -3.295e+05 to -3.254e+05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.43 -> 1.11; fit 92.9 % -> 96.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlBoreWearFrictionMild(Effect):
    name = "proposed_unl_bore_wear_friction_mild"
    title = "proposed term (piston force)"
    params = (
        Param("f_x2sv", "N/m^2", 327425, (0.0, 6.54851e+06),
              "force per m^2 of the piston position squared times the sign of the piston velocity, on the piston (fitted: -3.274e+05, 95 % CI -3.295e+05 to -3.254e+05)", typical=(163713, 654851)),
    )
    main_param = "f_x2sv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) with c_x2sv = -3.274e+05 N/m^2 (95 % CI -3.295e+05 to -3.254e+05)'
    signature = 'the residual it was fitted to: x^2 tanh(v / v_tanh)'

    @staticmethod
    def piston_force(x, v, v_tanh, f_x2sv):
        return -(f_x2sv * (x ** 2) * (math.tanh(v / v_tanh)))
