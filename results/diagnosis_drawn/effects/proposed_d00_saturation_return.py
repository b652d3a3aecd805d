"""proposed_d00_saturation_return: a term proposed by ehas diagnose for /tmp/dr1_work/d00_saturation@return/campaign.

(Q_A, Q_B) [m^3/s] += c_ret·the outflow land's flow times -1 / (2 p_out): return back-pressure   with c_ret = 2.159e+05 Pa (95 % CI 2.086e+05 to 2.232e+05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.9 -> 1.34; fit 90.5 % -> 96.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD00SaturationReturn(Effect):
    name = "proposed_d00_saturation_return"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_ret", "Pa", 215886, (0.0, 4.31773e+06),
              "back-pressure of the return line (tank above 0) (fitted: 2.159e+05, 95 % CI 2.086e+05 to 2.232e+05)", typical=(107943, 431773)),
    )
    main_param = "q_ret"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_ret·the outflow land's flow times -1 / (2 p_out): return back-pressure with c_ret = 2.159e+05 Pa (95 % CI 2.086e+05 to 2.232e+05)"
    signature = "the residual it was fitted to: the outflow land's flow times -1 / (2 p_out): return back-pressure"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_ret):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqb -= q_ret * q_b / (2.0 * max(pb, 1.0e5))
        else:
            dqa -= q_ret * q_a / (2.0 * max(pa, 1.0e5))
        return dqa, dqb
