"""proposed_pair_load_compliance_valve_underlap: underlapped valve: lands open at null, found by ehas diagnose on /tmp/ow/work/pair_load_compliance+valve_underlap/campaign.

The valve is underlapped by the flow of 0.232 mA: around null its supply and return lands are open together.
i_u = 0.232 mA (95 % CI 0.2296 to 0.2344)
Residual against what does not repeat: 46.2x -> 1.19x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedPairLoadComplianceValveUnderlap(Effect):
    name = "proposed_pair_load_compliance_valve_underlap"
    title = "underlapped valve: lands open at null"
    valve_side = True  # flow through the metering lands: a meter in line A (and the bench's) reads it
    params = (
        Param("i_u", "mA", 0.231952, (0.0, 8.0),
              "the underlap, as the current that moves the spool by it: within +-i_u of null all four lands are "
              "open (assumed range: a worn or deliberately open-centred spool, up to 40 % of the rated current)",
              typical=(0.115976, 0.463904), log_scale=True),
    )
    main_param = "i_u"
    explanation = (
        "The baseline's spool is critically lapped: at null every metering land is just closed. Worn edges or an "
        "open-centred design leave each land open by the underlap, the flow of i_u mA (Merritt's underlapped "
        "valve): within +-i_u the supply and return lands of each chamber are open together, so the flow gain "
        "near null is doubled and oil flows from supply to tank through the valve at rest; outside, each "
        "opening is larger by the underlap."
    )
    signature = (
        "near null a flow gain above the model's and a current residual that changes with the sign of the "
        "spool; chamber pressures held near mid-supply at rest; on valve runs a flow residual largest at small "
        "currents."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the valve is underlapped by the flow of {params['i_u']:.3g} mA: around null its supply and "
                f"return lands are open together")

    @staticmethod
    def chamber_flows(qc, pa, pb, ps, rated_drop, K, i_u):
        half = 0.5 * rated_drop
        qu = K * i_u

        def root(z):
            return math.copysign(math.sqrt(abs(z)), z)

        # the baseline's critically lapped lands ...
        if qc >= 0.0:
            qa0, qb0 = qc * root((ps - pa) / half), -qc * root(pb / half)
        else:
            qa0, qb0 = qc * root(pa / half), -qc * root((ps - pb) / half)
        # ... and the underlapped ones: each land's opening is the spool's plus the underlap
        qa1 = max(qc + qu, 0.0) * root((ps - pa) / half) - max(qu - qc, 0.0) * root(pa / half)
        qb1 = max(qu - qc, 0.0) * root((ps - pb) / half) - max(qc + qu, 0.0) * root(pb / half)
        return qa1 - qa0, qb1 - qb0
