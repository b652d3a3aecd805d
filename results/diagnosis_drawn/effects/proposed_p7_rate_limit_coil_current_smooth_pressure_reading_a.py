"""proposed_p7_rate_limit_coil_current_smooth_pressure_reading_a: a term proposed by ehas diagnose for /work/runs/drawn/p7_rate_limit@coil_current+smooth@pressure_reading_a/campaign.

(Q_A, Q_B) [m^3/s] += c_intsq·(-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|)   with c_intsq = -1.995e-10 m^3/(Pa^0.5 s) (95 % CI -2.265e-10 to -1.724e-10)

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
        Param("q_intsq", "m^3/(Pa^0.5 s)", 1.99451e-10, (0.0, 3.98902e-09),
              "turbulent leakage across the piston, from A to B: flow per N^0.5/m (fitted: -1.995e-10, 95 % CI -2.265e-10 to -1.724e-10)", typical=(9.97256e-11, 3.98902e-10)),
    )
    main_param = "q_intsq"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_intsq·(-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|) with c_intsq = -1.995e-10 m^3/(Pa^0.5 s) (95 % CI -2.265e-10 to -1.724e-10)'
    signature = 'the residual it was fitted to: (-sign(p_L) sqrt|p_L|, +sign(p_L) sqrt|p_L|)'

    @staticmethod
    def chamber_flows(pa, pb, q_intsq):
        dqa = 0.0
        dqb = 0.0
        dqa -= (-q_intsq) * math.copysign(math.sqrt(abs((pa - pb))), (pa - pb))
        dqb += (-q_intsq) * math.copysign(math.sqrt(abs((pa - pb))), (pa - pb))
        return dqa, dqb
