"""proposed_d07_saturation_piston_force: a term proposed by ehas diagnose for /work/runs/held/d07_saturation@piston_force/campaign.

F_piston [N] += c_pa·p_A   with c_pa = -1.204e-06 m^2 (95 % CI -1.808e-06 to -6.003e-07)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.96 -> 2.69; fit 93.4 % -> 93.3 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD07SaturationPistonForce(Effect):
    name = "proposed_d07_saturation_piston_force"
    title = "proposed term (piston force)"
    params = (
        Param("f_pa", "m^2", 1.20417e-06, (0.0, 2.40835e-05),
              "force per N/m^2 of chamber A's pressure, on the piston (fitted: -1.204e-06, 95 % CI -1.808e-06 to -6.003e-07)", typical=(6.02087e-07, 2.40835e-06)),
    )
    main_param = "f_pa"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pa·p_A with c_pa = -1.204e-06 m^2 (95 % CI -1.808e-06 to -6.003e-07)'
    signature = 'the residual it was fitted to: p_A'

    @staticmethod
    def piston_force(pa, f_pa):
        return -(f_pa * pa)
