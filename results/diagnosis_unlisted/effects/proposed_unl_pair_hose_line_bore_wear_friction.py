"""proposed_unl_pair_hose_line_bore_wear_friction: a term proposed by ehas diagnose for /work/runs/unl/unl_pair_hose_line+bore_wear_friction/campaign.

F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh)   with c_x2sv = -3.575e+05 N/m^2 (95 % CI -3.732e+05 to -3.418e+05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 11.6 -> 1.77; fit 82.2 % -> 96.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairHoseLineBoreWearFriction(Effect):
    name = "proposed_unl_pair_hose_line_bore_wear_friction"
    title = "proposed term (piston force)"
    params = (
        Param("f_x2sv", "N/m^2", 357523, (0.0, 7.15047e+06),
              "force per m^2 of the piston position squared times the sign of the piston velocity, on the piston (fitted: -3.575e+05, 95 % CI -3.732e+05 to -3.418e+05)", typical=(178762, 715047)),
    )
    main_param = "f_x2sv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) with c_x2sv = -3.575e+05 N/m^2 (95 % CI -3.732e+05 to -3.418e+05)'
    signature = 'the residual it was fitted to: x^2 tanh(v / v_tanh)'

    @staticmethod
    def piston_force(x, v, v_tanh, f_x2sv):
        return -(f_x2sv * (x ** 2) * (math.tanh(v / v_tanh)))
