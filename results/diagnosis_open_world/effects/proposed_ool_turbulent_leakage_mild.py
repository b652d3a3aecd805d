"""proposed_ool_turbulent_leakage_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_turbulent_leakage_mild/campaign.

F_piston [N] += c_x·x   with c_x = 1160 N/m (95 % CI 710.1 to 1610)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 8.01 -> 7.76; fit 93.7 % -> 93.6 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolTurbulentLeakageMild(Effect):
    name = "proposed_ool_turbulent_leakage_mild"
    title = "proposed term (piston force)"
    params = (
        Param("f_x", "N/m", 1159.97, (0.0, 23199.4),
              "spring on the piston: force per metre of stroke (fitted: 1160, 95 % CI 710.1 to 1610)", typical=(579.986, 2319.94)),
    )
    main_param = "f_x"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x·x with c_x = 1160 N/m (95 % CI 710.1 to 1610)'
    signature = 'the residual it was fitted to: x'

    @staticmethod
    def piston_force(x, f_x):
        return (f_x * x)
