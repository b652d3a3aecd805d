"""Each black-box structure on simulated ARMAX, OE and BJ data: fit %, residual whiteness, time.

Regenerates the second table of results/identification/structures.md:

    python tests/identification/scripts/structures_sim.py
"""


def main():
    # imported here: the test run imports this file for doctests, and these packages are not its
    import numpy as np, time
    from scipy.signal import lfilter
    from ehas_env.identification.pem import estimate
    from ehas_env.identification.fit import residual_analysis
    rng = np.random.default_rng(3)
    N = 3000
    u = np.sign(rng.normal(size=N))
    e = 0.2 * rng.normal(size=N)
    A=[1,-1.5,0.7]; B=[1.0,0.5]; C=[1,0.5]; D=[1,-0.9]; F=[1,-1.5,0.7]
    cases = {
     "armax": (lfilter([0]+B, A, u) + lfilter(C, A, e), {"na":2,"nb":2,"nc":1,"nk":1}),
     "oe": (lfilter([0]+B, F, u) + e, {"nb":2,"nf":2,"nk":1}),
     "bj": (lfilter([0]+B, F, u) + lfilter(C, D, e), {"nb":2,"nc":1,"nd":1,"nf":2,"nk":1}),
    }
    for s,(y,o) in cases.items():
        for st in ("arx","armax","oe","bj","ss"):
            oo = o if st==s else None
            t0=time.perf_counter()
            m = estimate(st, u, y, oo)
            ra = residual_analysis(m.residuals, u)
            print(f"data {s:5s} model {st:5s} fit {m.fit_percent:6.2f} auto_out {ra.auto_outside():2d} cross {ra.cross_outside():2d} {time.perf_counter()-t0:.2f}s")
            if st==s: print(m.summary())


if __name__ == "__main__":
    main()
