"""proposed_p7_rate_limit_coil_current_smooth_pressure_reading_a: a term proposed by ehas diagnose for /tmp/s1/work/p7_rate_limit@coil_current+smooth@pressure_reading_a/campaign.

(Q_A, Q_B) [m^3/s] += c_intsq·(-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|)   with c_intsq = -1.993e-10 m^3/s/Pa^0.5 (95 % CI -2.264e-10 to -1.722e-10)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.61 -> 2.45; fit 94.3 % -> 94.3 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedP7RateLimitCoilCurrentSmoothPressureReadingA(Effect):
    name = "proposed_p7_rate_limit_coil_current_smooth_pressure_reading_a"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_intsq", "m^3/s/Pa^0.5", 1.993e-10, (0.0, 3.98601e-09),
              "turbulent leakage across the piston, per sqrt(Pa) of load pressure (fitted: -1.993e-10, 95 % CI -2.264e-10 to -1.722e-10)", typical=(9.96502e-11, 3.98601e-10)),
    )
    main_param = "q_intsq"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_intsq·(-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|) with c_intsq = -1.993e-10 m^3/s/Pa^0.5 (95 % CI -2.264e-10 to -1.722e-10)'
    signature = 'the residual it was fitted to: (-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|)'

    @staticmethod
    def chamber_flows(pa, pb, q_intsq):
        dqa = 0.0
        dqb = 0.0
        dqa -= (-q_intsq) * math.copysign(math.sqrt(abs(pa - pb)), pa - pb)
        dqb += (-q_intsq) * math.copysign(math.sqrt(abs(pa - pb)), pa - pb)
        return dqa, dqb
