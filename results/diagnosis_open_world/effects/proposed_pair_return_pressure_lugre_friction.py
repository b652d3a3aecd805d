"""proposed_pair_return_pressure_lugre_friction: a term proposed by ehas diagnose for /tmp/ehas_open_world/pair_return_pressure+lugre_friction/campaign.

F_piston [N] += c_v·v   with c_v = -362.8 N s/m (95 % CI -388.4 to -337.3)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 6.83 -> 5.79; fit 73.3 % -> 75.2 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedPairReturnPressureLugreFriction(Effect):
    name = "proposed_pair_return_pressure_lugre_friction"
    title = "proposed term (piston force)"
    params = (
        Param("f_v", "N s/m", 362.842, (0.0, 7256.84),
              "viscous force per m/s (fitted: -362.8, 95 % CI -388.4 to -337.3)", typical=(181.421, 725.684)),
    )
    main_param = "f_v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_v·v with c_v = -362.8 N s/m (95 % CI -388.4 to -337.3)'
    signature = 'the residual it was fitted to: v'

    @staticmethod
    def piston_force(v, f_v):
        return -(f_v * v)
