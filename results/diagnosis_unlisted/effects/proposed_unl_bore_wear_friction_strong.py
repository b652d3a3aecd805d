"""proposed_unl_bore_wear_friction_strong: a term proposed by ehas diagnose for /work/runs/unl/unl_bore_wear_friction_strong/campaign.

F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh)   with c_x2sv = -9.773e+05 N/m^2 (95 % CI -9.788e+05 to -9.759e+05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.55 -> 1.1; fit 84.5 % -> 97.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlBoreWearFrictionStrong(Effect):
    name = "proposed_unl_bore_wear_friction_strong"
    title = "proposed term (piston force)"
    params = (
        Param("f_x2sv", "N/m^2", 977319, (0.0, 1.95464e+07),
              "force per m^2 of the piston position squared times the sign of the piston velocity, on the piston (fitted: -9.773e+05, 95 % CI -9.788e+05 to -9.759e+05)", typical=(488659, 1.95464e+06)),
    )
    main_param = "f_x2sv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) with c_x2sv = -9.773e+05 N/m^2 (95 % CI -9.788e+05 to -9.759e+05)'
    signature = 'the residual it was fitted to: x^2 tanh(v / v_tanh)'

    @staticmethod
    def piston_force(x, v, v_tanh, f_x2sv):
        return -(f_x2sv * (x ** 2) * (math.tanh(v / v_tanh)))
