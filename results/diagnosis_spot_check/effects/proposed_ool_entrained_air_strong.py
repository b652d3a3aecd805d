"""proposed_ool_entrained_air_strong: entrained air: a bulk modulus that falls at low pressure, found by ehas diagnose on /tmp/sc_work/ool_entrained_air_strong/campaign.

The oil carries 24.3 % of free air (at atmospheric pressure): its bulk modulus is 0.05 of the oil's at 10 bar, nearly the oil's at 100 bar.
air = 24.27 % (95 % CI 21.25 to 27.7)
Residual against what does not repeat: 1.37x -> 1.01x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolEntrainedAirStrong(Effect):
    name = "proposed_ool_entrained_air_strong"
    title = "entrained air: a bulk modulus that falls at low pressure"
    params = (
        Param("air", "%", 24.2656, (0.0, 50.0),
              "volume of free air in the oil at atmospheric pressure, per cent of the oil's volume, in the "
              "isothermal law (assumed range: 0.1 % for well-bled systems to several % for aerated ones; the bound "
              "is wider because air that compresses polytropically, exponent n up to 1.4, gives the isothermal law's "
              "compressibility at 10-100 bar with (p / p_atm)^(1 - 1/n) / n = 1.4-2.7 times its own fraction)",
              typical=(12.1328, 48.5312), log_scale=True, si=0.01),
    )
    constants = (
        Param("p_atm", "Pa", 1.0e5, (0.0, 1e6), "atmospheric pressure; chamber pressures are gauge (book: tank at 0)"),
        Param("p_min", "Pa", 2.0e4, (0.0, 1e6),
              "least absolute pressure the air's law is evaluated at (assumed: dissolved gas keeps a cavitating "
              "chamber from the law's singularity)"),
    )
    main_param = "air"
    # a lower constant bulk modulus takes up part of its signature (the library's recalibration of beta)
    mistaken_for = ("bulk_modulus",)
    explanation = (
        "Air bubbles in the oil are compressed isothermally: a volume fraction a at atmospheric pressure adds "
        "a p_atm / p^2 to the fluid's compressibility, 1 / beta_eff = 1 / beta + a p_atm / p^2 (p absolute). "
        "The oil is soft at low chamber pressure and stiff at high: unlike a lower constant bulk modulus, the "
        "hydraulic spring changes over each cycle with the pressures."
    )
    signature = (
        "pressure residuals largest where a chamber is near tank pressure (the draining side), small at high "
        "pressure; a hydraulic resonance that shifts over the cycle; a constant bulk modulus fitted to it "
        "differs between runs at different pressures."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        a = params["air"] * 0.01
        at10 = 1.0 / (1.0 + 1.0e9 * a * 1.0e5 / (11.0e5) ** 2)
        return (f"the oil carries {params['air']:.3g} % of free air (at atmospheric pressure): its bulk modulus is "
                f"{at10:.2f} of the oil's at 10 bar, nearly the oil's at 100 bar")

    @staticmethod
    def chamber_flows(pa, pb, q_a, q_b, v, area, beta, air, p_atm, p_min):
        # continuity with beta_eff instead of beta: the extra flow that scales the chamber's rate by beta_eff/beta
        pa_abs = max(pa + p_atm, p_min)
        pb_abs = max(pb + p_atm, p_min)
        ra = 1.0 / (1.0 + beta * air * p_atm / (pa_abs * pa_abs))
        rb = 1.0 / (1.0 + beta * air * p_atm / (pb_abs * pb_abs))
        return (q_a - area * v) * (ra - 1.0), (q_b + area * v) * (rb - 1.0)
