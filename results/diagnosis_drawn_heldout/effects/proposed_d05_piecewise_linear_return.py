"""proposed_d05_piecewise_linear_return: a term proposed by ehas diagnose for /tmp/drH_work/d05_piecewise_linear@return/campaign.

(Q_A, Q_B) [m^3/s] += c_sup·the inflow land's flow times 1 / (2 (p_S - p_in)): supply offset   with c_sup = 1.3e+05 Pa (95 % CI 1.147e+05 to 1.453e+05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.37 -> 4.29; fit 79.9 % -> 83.6 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD05PiecewiseLinearReturn(Effect):
    name = "proposed_d05_piecewise_linear_return"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_sup", "Pa", 129984, (0.0, 2.59969e+06),
              "supply pressure offset at the valve (fitted: 1.3e+05, 95 % CI 1.147e+05 to 1.453e+05)", typical=(64992.2, 259969)),
    )
    main_param = "q_sup"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_sup·the inflow land's flow times 1 / (2 (p_S - p_in)): supply offset with c_sup = 1.3e+05 Pa (95 % CI 1.147e+05 to 1.453e+05)"
    signature = "the residual it was fitted to: the inflow land's flow times 1 / (2 (p_S - p_in)): supply offset"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_sup):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqa += q_sup * q_a / (2.0 * max(ps - pa, 1.0e5))
        else:
            dqb += q_sup * q_b / (2.0 * max(ps - pb, 1.0e5))
        return dqa, dqb
