"""proposed_p0_dead_zone_piston_force_compliance_crank_torque: a term proposed by ehas diagnose for /tmp/drH_work/p0_dead_zone@piston_force+compliance@crank_torque/campaign.

F_piston [N] += c_x2v·x^2 v   with c_x2v = 1.632e+06 N s/m^3 (95 % CI 1.565e+06 to 1.699e+06)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.79 -> 2.03; fit 95.2 % -> 95.9 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP0DeadZonePistonForceComplianceCrankTorque(Effect):
    name = "proposed_p0_dead_zone_piston_force_compliance_crank_torque"
    title = "proposed term (piston force)"
    params = (
        Param("f_x2v", "N s/m^3", 1.63219e+06, (0.0, 3.26438e+07),
              "viscous force that rises with position squared: per m^2 and per m/s (fitted: 1.632e+06, 95 % CI 1.565e+06 to 1.699e+06)", typical=(816095, 3.26438e+06)),
    )
    main_param = "f_x2v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2v·x^2 v with c_x2v = 1.632e+06 N s/m^3 (95 % CI 1.565e+06 to 1.699e+06)'
    signature = 'the residual it was fitted to: x^2 v'

    @staticmethod
    def piston_force(x, v, f_x2v):
        return (f_x2v * x ** 2 * v)
