"""proposed_ool_return_pressure_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_return_pressure_mild/campaign.

(Q_A, Q_B) [m^3/s] += c_ext·(-p_A, -p_B)   with c_ext = -2.463e-14 m^3/s/Pa (95 % CI -3.647e-14 to -1.28e-14)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.62 -> 5.01; fit 75.0 % -> 80.4 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolReturnPressureMild(Effect):
    name = "proposed_ool_return_pressure_mild"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_ext", "m^3/s/Pa", 2.46304e-14, (0.0, 4.92608e-13),
              "leakage from each chamber to drain, per Pa (fitted: -2.463e-14, 95 % CI -3.647e-14 to -1.28e-14)", typical=(1.23152e-14, 4.92608e-14)),
    )
    main_param = "q_ext"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_ext·(-p_A, -p_B) with c_ext = -2.463e-14 m^3/s/Pa (95 % CI -3.647e-14 to -1.28e-14)'
    signature = 'the residual it was fitted to: (-p_A, -p_B)'

    @staticmethod
    def chamber_flows(pa, pb, q_ext):
        dqa = 0.0
        dqb = 0.0
        dqa -= (-q_ext) * pa
        dqb -= (-q_ext) * pb
        return dqa, dqb
