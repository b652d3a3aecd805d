"""proposed_ool_turbulent_leakage_mild: turbulent (orifice-law) leakage across the piston, found by ehas diagnose on /tmp/ow/work/ool_turbulent_leakage_mild/campaign.

Oil leaks across the piston as through an orifice: 0.399 LPM at 100 bar load pressure, growing with the square root of the pressure.
q_100 = 0.3992 LPM (95 % CI 0.3985 to 0.4)
Residual against what does not repeat: 9.28x -> 1.08x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolTurbulentLeakageMild(Effect):
    name = "proposed_ool_turbulent_leakage_mild"
    title = "turbulent (orifice-law) leakage across the piston"
    params = (
        Param("q_100", "LPM", 0.39924, (0.0, 20.0),
              "leakage flow from the high- to the low-pressure chamber at 100 bar load pressure (assumed range: "
              "a scored bore or a broken seal ring, up to a fifth of the valve's rating)",
              typical=(0.19962, 0.798481), log_scale=True, si=1.0e-3 / 60.0),
    )
    constants = (
        Param("p_lam", "Pa", 2.0e5, (1.0e3, 1e7),
              "load pressure below which the leak is laminar (assumed: a Reynolds transition at a few bar; it "
              "keeps the law's slope finite at zero; from 5 p_lam up the flow is the orifice law's within 1 %)"),
    )
    main_param = "q_100"
    explanation = (
        "A scored bore, a broken piston ring or a short clearance passes oil from the high- to the low-pressure "
        "chamber as an orifice does: Q = q_100 sqrt(|P_L| / 100 bar) sign(P_L), laminar below a few bar. "
        "Against the library's laminar leakage (Q proportional to P_L) it leaks relatively more at low load "
        "pressure and less at the peaks."
    )
    signature = (
        "current residual that follows the square root of the load pressure; the hydraulic mode damped at "
        "small load as much as at large; a laminar leakage fitted to it comes out larger at small loads than "
        "at large ones."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"oil leaks across the piston as through an orifice: {params['q_100']:.3g} LPM at 100 bar load "
                f"pressure, growing with the square root of the pressure")

    @staticmethod
    def chamber_flows(p_load, q_100, p_lam):
        # p / (p^2 + p_lam^2)^(1/4): the orifice law sqrt(|p|) sign(p) above a few p_lam (within 1 % from
        # 5 p_lam), linear (laminar) through zero with a finite slope; normalised so that q_100 flows at 100 bar
        ref = 1.0e7 / (1.0e14 + p_lam * p_lam) ** 0.25
        q = q_100 * p_load / ((p_load * p_load + p_lam * p_lam) ** 0.25 * ref)
        return -q, q
