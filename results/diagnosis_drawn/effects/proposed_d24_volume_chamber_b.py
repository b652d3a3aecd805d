"""proposed_d24_volume_chamber_b: a term proposed by ehas diagnose for /tmp/drX_work/d24_volume@chamber_b/campaign.

F_piston [N] += c_x3·x^3   with c_x3 = -6.321e+06 N/m^3 (95 % CI -7.318e+06 to -5.324e+06)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.64 -> 3.3; fit 86.4 % -> 86.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD24VolumeChamberB(Effect):
    name = "proposed_d24_volume_chamber_b"
    title = "proposed term (piston force)"
    params = (
        Param("f_x3", "N/m^3", 6.32113e+06, (0.0, 1.26423e+08),
              "hardening spring: force per m^3 (fitted: -6.321e+06, 95 % CI -7.318e+06 to -5.324e+06)", typical=(3.16056e+06, 1.26423e+07)),
    )
    main_param = "f_x3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x3·x^3 with c_x3 = -6.321e+06 N/m^3 (95 % CI -7.318e+06 to -5.324e+06)'
    signature = 'the residual it was fitted to: x^3'

    @staticmethod
    def piston_force(x, f_x3):
        return -(f_x3 * x ** 3)
