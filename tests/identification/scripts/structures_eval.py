"""Evaluate nfoursid, sysidentpy, harold on a simulated 2nd-order discrete system with noise.

Regenerates the evaluation numbers of results/identification/structures.md:

    pip install nfoursid==1.0.2 sysidentpy==0.9.0 harold==1.0.3
    python tests/identification/scripts/structures_eval.py
"""


def main():
    # imported here: the test run imports this file for doctests, and these packages are not its
    import time, numpy as np, pandas as pd, control
    from scipy.signal import lfilter
    rng = np.random.default_rng(1)
    N = 4000
    a = [1, -1.5, 0.7]; b = [0, 1.0, 0.5]
    u = np.sign(rng.normal(size=N))
    y0 = lfilter(b, a, u)
    e = 0.3 * rng.normal(size=N)
    y = y0 + e  # OE noise (white measurement noise)
    print("true poles", np.roots(a))
    def fitp(y, ys): return 100*(1-np.linalg.norm(y-ys)/np.linalg.norm(y-y.mean()))
    # nfoursid
    from nfoursid.nfoursid import NFourSID
    t0=time.perf_counter()
    df = pd.DataFrame({"u": u, "y": y})
    n4 = NFourSID(df, output_columns=["y"], input_columns=["u"], num_block_rows=10)
    n4.subspace_identification()
    ss, cov = n4.system_identification(rank=2)
    dt=time.perf_counter()-t0
    sys = control.ss(ss.a, ss.b, ss.c, ss.d, 1)
    ys = control.forced_response(sys, U=u).outputs
    print("nfoursid poles", np.linalg.eigvals(ss.a), "fit vs noisy %.2f, vs true %.2f, %.2fs" % (fitp(y, ys), fitp(y0, ys), dt))
    print("  singular values", np.round(np.diag(n4.R32_decomposition.eigenvalues)[:6], 2))
    # sysidentpy
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.basis_function import Polynomial
    t0=time.perf_counter()
    m = FROLS(order_selection=False, n_terms=4, ylag=2, xlag=2, basis_function=Polynomial(degree=1))
    m.fit(X=u.reshape(-1,1), y=y.reshape(-1,1))
    yhat = m.predict(X=u.reshape(-1,1), y=y[:2].reshape(-1,1))
    dt=time.perf_counter()-t0
    print("sysidentpy FROLS regressors", m.final_model.tolist(), "theta", np.round(m.theta.ravel(),3), "free-run fit %.2f vs true %.2f, %.2fs" % (fitp(y, yhat.ravel()), fitp(y0, yhat.ravel()), dt))
    import harold
    print("harold names with ident/estimat:", [n for n in dir(harold) if any(k in n.lower() for k in ("ident", "estim", "n4", "arx", "fit"))])


if __name__ == "__main__":
    main()
