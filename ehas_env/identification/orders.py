"""Model structures compared on one run: fit %, AIC, BIC, FPE on estimation and validation data, k-step prediction.

:func:`order_table` fits every structure of a range (poles 1..n, zeros
0..poles-1) on the estimation data and scores it on both parts (MATLAB's
``aic``/``fpe`` and ``compare``):

* the run is split: the first 2/3 estimate, the last 1/3 validates; the
  model is simulated over the whole run from rest (the estimation part is
  its warm-up) and scored on the last third only.  A second run
  (``validation=``) validates instead, simulated from rest;
* with V the mean squared simulation error over N samples and p estimated
  parameters (coefficients, delay, offsets):
  ``AIC = N ln V + 2 p + N (ln 2 pi + 1)``,
  ``BIC = N ln V + p ln N + N (ln 2 pi + 1)``,
  ``FPE = V (1 + p/N) / (1 - p/N)`` (MATLAB's definitions);
* the structure chosen is the one of the **lowest BIC on the validation
  data** (rule :data:`RULE`) among the usable ones: a fit that ends at an
  unstable model or a diverging simulation (more poles and zeros than the
  record determines, :meth:`~ehas_env.identification.fit.TFEstimate.usable`)
  is listed, marked "(unstable)", and never chosen;
* discrete-time black-box structures (ARX, ARMAX, OE, BJ, N4SID state
  space, :mod:`ehas_env.identification.pem`) can stand beside the transfer
  functions (``black_box=``), fitted on the same estimation part and scored
  by the same simulation criteria on the same validation part.

:func:`predict` gives the k-step-ahead prediction of an output-error model
with a noise model: an AR model of the residuals (order by BIC, at most
:data:`AR_MAX`), fitted on the estimation data.  The prediction
``yhat(t | t-k) = G u (t) + ehat(t | t-k)`` uses the measured output up to
t - k; with white residuals it equals the simulation, and k -> infinity
gives the simulation fit.

Examples
--------
>>> c = criteria(np.full(1000, 0.1), 3)
>>> round(c["FPE"] / (0.01 * (1 + 0.003) / (1 - 0.003)), 12), round(c["BIC"] - c["AIC"], 6) == round(3 * math.log(1000) - 6, 6)
(1.0, True)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

RULE = "lowest BIC on the validation data"
ESTIMATION_SHARE = 2.0 / 3.0
#: largest AR order of the residual noise model of :func:`predict`
AR_MAX = 30


def criteria(e, p: int) -> dict:
    """``{"V", "AIC", "BIC", "FPE"}`` of the residuals ``e`` for ``p`` parameters (MATLAB's definitions)."""
    e = np.asarray(e, float)
    N = e.size
    V = float(e @ e) / N
    const = N * (math.log(2 * math.pi) + 1.0)
    lnV = math.log(V) if V > 0 else -745.0
    return {"V": V, "AIC": N * lnV + 2 * p + const, "BIC": N * lnV + p * math.log(N) + const,
            "FPE": V * (1 + p / N) / (1 - p / N) if p < N else math.inf}


def split(data, share: float = ESTIMATION_SHARE):
    """(estimation record, index where validation starts): the first ``share`` of the run."""
    from ehas_env.identification.fit import IdData

    k = int(round(share * data.n))
    est = IdData(t=data.t[:k], u=data.u[:k], y=data.y[:k], dt=data.dt, input_name=data.input_name,
                 output_name=data.output_name, source=f"{data.source} (first {k} samples)")
    return est, k


def n_parameters(est) -> int:
    """Estimated parameters of a fit: coefficients plus delay, offsets and initial state if estimated."""
    p = est.n_poles + est.n_zeros + 1
    for key in est.estimated:
        p += est.n_poles if key == "x0" else 1
    return p


# -- the k-step-ahead predictor -----------------------------------------------------------------------

def fit_ar(e, max_order: int = AR_MAX) -> np.ndarray:
    """AR coefficients c of ``e(t) = sum_i c_i e(t-i) + w(t)``, the order by BIC (least squares).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> w = rng.normal(size=20000)
    >>> e = np.zeros_like(w)
    >>> for k in range(1, w.size): e[k] = 0.8 * e[k - 1] + w[k]
    >>> np.round(fit_ar(e), 2).tolist()
    [0.8]
    """
    e = np.asarray(e, float)
    N = e.size
    best = (criteria(e, 0)["BIC"], np.zeros(0))
    max_order = int(min(max_order, N // 20))
    for q in range(1, max_order + 1):
        X = np.column_stack([e[q - i: N - i] for i in range(1, q + 1)])
        c, *_ = np.linalg.lstsq(X, e[q:], rcond=None)
        b = criteria(e[q:] - X @ c, q)["BIC"] * N / (N - q)
        if b < best[0]:
            best = (b, c)
    return best[1]


def predict_residual(e, c, k: int) -> np.ndarray:
    """``ehat(t | t-k)``: the AR model's k-step prediction of the residual from its values up to t - k.

    Examples
    --------
    >>> predict_residual(np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.5]), 2).tolist()
    [0.0, 0.0, 0.25, 0.5]
    """
    e = np.asarray(e, float)
    N = e.size
    q = c.size
    if q == 0:
        return np.zeros(N)
    # P[j][t]: prediction of e(t) from e up to t - j; P[0] = e
    P = [e]
    for j in range(1, k + 1):
        pj = np.zeros(N)
        for i in range(1, q + 1):
            src = e if i >= j else P[j - i]
            pj[i:] += c[i - 1] * src[: N - i]
        P.append(pj)
    return P[k]


def predict(est, k: int, t=None, u=None, y=None, ar=None) -> np.ndarray:
    """k-step-ahead prediction of an output-error fit with an AR noise model of its residuals.

    Parameters
    ----------
    est : TFEstimate
        The fit (its residuals on its own record give the noise model unless ``ar`` is given).
    k : int
        Steps ahead, >= 1.
    t, u, y : array, optional
        Another record to predict (default: the fit's own).
    ar : ndarray, optional
        AR coefficients of the noise model (default :func:`fit_ar` of the fit's residuals).

    Returns
    -------
    ndarray
        ``yhat(t | t-k)``.
    """
    if not (isinstance(k, (int, np.integer)) and k >= 1):
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    c = fit_ar(est.residuals) if ar is None else np.asarray(ar, float)
    if t is None:
        y_sim, y = est.y_sim, est.data.y
    else:
        y_sim = est.simulate(t, u)
        y = np.asarray(y, float)
    return y_sim + predict_residual(y - y_sim, c, int(k))


# -- the table ---------------------------------------------------------------------------------------

@dataclass
class OrderRow:
    """One structure's scores (see the module docstring); ``structure`` tf (poles, zeros) or a black-box one."""

    poles: int
    zeros: int
    p: int
    estimation: dict
    validation: dict
    est: object = field(repr=False, default=None)
    y_val: np.ndarray = field(repr=False, default=None)
    structure: str = "tf"
    #: the model is stable and its simulations finite (an unusable row is listed, never chosen)
    usable: bool = True

    @property
    def label(self) -> str:
        return f"{self.poles}p{self.zeros}z" if self.structure == "tf" else self.est.label

    def to_json_dict(self) -> dict:
        if self.structure != "tf":
            return {"structure": self.structure, "label": self.label, "parameters": self.p, "usable": self.usable,
                    "model": self.est.to_json_dict(), "estimation": self.estimation, "validation": self.validation}
        return {"structure": "tf", "label": self.label, "poles": self.poles, "zeros": self.zeros,
                "parameters": self.p, "usable": self.usable, "num": [float(v) for v in self.est.num],
                "den": [float(v) for v in self.est.den], "delay_s": float(self.est.delay_s),
                "estimation": self.estimation, "validation": self.validation}


@dataclass
class OrderTable:
    """Rows of :func:`order_table`, the structure chosen and how the data were split."""

    rows: list
    chosen: OrderRow
    validation_source: str
    n_estimation: int
    n_validation: int
    predict_k: int | None = None
    rule: str = RULE

    def to_json_dict(self) -> dict:
        return {"rows": [r.to_json_dict() for r in self.rows],
                "chosen": {"label": self.chosen.label, "structure": self.chosen.structure, "poles": self.chosen.poles,
                           "zeros": self.chosen.zeros, "rule": self.rule},
                "validation": self.validation_source, "estimation_samples": self.n_estimation,
                "validation_samples": self.n_validation, "predict_steps": self.predict_k}

    def markdown(self) -> str:
        """The table as markdown (also readable as text)."""
        pk = self.predict_k
        head = ["model", "p", "fit % est", "fit % val"] + ([f"{pk}-step fit % val"] if pk else []) + \
            ["AIC est", "BIC est", "FPE est", "AIC val", "BIC val", "FPE val"]
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in self.rows:
            e, v = r.estimation, r.validation
            cells = [r.label + (" **chosen**" if r is self.chosen else "") + ("" if r.usable else " (unstable)"),
                     str(r.p), f"{e['fit_percent']:.2f}",
                     f"{v['fit_percent']:.2f}"] + ([f"{v['predict_fit_percent']:.2f}"] if pk else []) + \
                [f"{e['AIC']:.1f}", f"{e['BIC']:.1f}", f"{e['FPE']:.4g}", f"{v['AIC']:.1f}", f"{v['BIC']:.1f}",
                 f"{v['FPE']:.4g}"]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        lines.append(f"Estimation: {self.n_estimation} samples; validation: {self.validation_source} "
                     f"({self.n_validation} samples). Chosen: {self.chosen.label} ({self.rule}).")
        return "\n".join(lines)


def parse_orders(text: str, where: str = "--orders") -> list[int]:
    """``"1:3"`` -> [1, 2, 3]; ``"2"`` -> [2]; pole counts 1..10.

    >>> parse_orders("1:3"), parse_orders("2")
    ([1, 2, 3], [2])
    """
    import re

    s = str(text).strip()
    m = re.fullmatch(r"(\d+)\s*(?::\s*(\d+))?", s)
    if not m:
        raise ValueError(f"{where} must be POLES or LO:HI with pole counts in [1, 10], e.g. 1:3, got {text!r}")
    lo = int(m.group(1))
    hi = int(m.group(2)) if m.group(2) else lo
    if not (1 <= lo <= hi <= 10):
        raise ValueError(f"{where} must be POLES or LO:HI with 1 <= LO <= HI <= 10 poles, got {text!r}")
    return list(range(lo, hi + 1))


def black_box_orders(structure: str, n: int, nk: int = 1) -> dict:
    """The orders of a black-box ``structure`` "of order n": every polynomial of degree n, or n states.

    >>> black_box_orders("bj", 2), black_box_orders("ss", 3)
    ({'nb': 2, 'nc': 2, 'nd': 2, 'nf': 2, 'nk': 1}, {'nx': 3})
    """
    from ehas_env.identification.pem import ORDERS

    return {k: (nk if k == "nk" else n) for k in ORDERS[structure]}


def _black_box_row(structure, n, nk, est_data, data, validation, k0, offsets, predict_k, val_y):
    """A black-box row: fitted on the estimation part (means removed per ``offsets``), scored like the tf rows."""
    from ehas_env.identification.fit import fit_percent
    from ehas_env.identification.pem import estimate

    u0 = float(np.mean(est_data.u)) if offsets == "estimate" else 0.0
    y0 = float(np.mean(est_data.y)) if offsets in ("output", "estimate") else 0.0
    m = estimate(structure, est_data.u - u0, est_data.y - y0, black_box_orders(structure, n, nk), dt=est_data.dt)
    p = m.n_parameters + {"none": 0, "output": 1, "estimate": 2}[offsets]
    y_est = m.simulate(est_data.u - u0) + y0
    if validation is None:
        y_all = m.simulate(data.u - u0) + y0
        y_val = y_all[k0:]
    else:
        y_val = m.simulate(validation.u - u0) + y0
    e_crit = {"fit_percent": float(fit_percent(est_data.y, y_est)), **criteria(est_data.y - y_est, p)}
    v_crit = {"fit_percent": float(fit_percent(val_y, y_val)), **criteria(val_y - y_val, p)}
    if predict_k:
        rec = data if validation is None else validation
        yp = m.predict(rec.u - u0, rec.y - y0, predict_k) + y0
        v_crit["predict_fit_percent"] = float(fit_percent(val_y, yp[k0:] if validation is None else yp))
        e_crit["predict_fit_percent"] = float(fit_percent(
            est_data.y, m.predict(est_data.u - u0, est_data.y - y0, predict_k) + y0))
    # an unstable plant can look finite over one record (its input gain fitted to almost nothing): listed, never chosen
    stable = bool(np.all(np.abs(m.poles()) < 1.0))
    return OrderRow(poles=n, zeros=0, p=p, estimation=e_crit, validation=v_crit, est=m, y_val=y_val,
                    structure=structure,
                    usable=stable and bool(np.all(np.isfinite(y_val)) and np.isfinite(v_crit["BIC"])))


def choose(rows: list) -> OrderRow:
    """The row of the lowest validation BIC among the usable ones (all rows when none is usable).

    Parameters
    ----------
    rows : list of OrderRow

    Returns
    -------
    OrderRow

    Examples
    --------
    >>> a = OrderRow(2, 0, 3, {}, {"BIC": 10.0})
    >>> b = OrderRow(3, 2, 6, {}, {"BIC": 5.0}, usable=False)
    >>> choose([a, b]) is a
    True
    """
    return min([r for r in rows if r.usable] or rows, key=lambda r: r.validation["BIC"])


def order_table(data, poles, *, validation=None, intersample: str = "zoh", delay=0.0, offsets: str = "none",
                predict_k: int | None = None, max_delay_s: float | None = None, black_box=(), nk: int = 1,
                tf: bool = True, share: float = ESTIMATION_SHARE) -> OrderTable:
    """Fit every structure with ``poles`` poles (and 0..poles-1 zeros) and score it.

    Parameters
    ----------
    data : IdData
        The run; without ``validation`` its first 2/3 estimate and its last 1/3 validates.
    poles : list of int
        Pole counts.
    validation : IdData, optional
        A second run that validates (the whole of ``data`` then estimates).
    intersample, delay, offsets, max_delay_s
        As :func:`ehas_env.identification.fit.tfest`.
    predict_k : int, optional
        Also the k-step-ahead prediction fit on the validation data (:func:`predict`; a black-box model
        predicts with its own noise model).
    black_box : sequence of str
        Discrete-time structures (:mod:`ehas_env.identification.pem`: arx, armax, oe, bj, ss) fitted beside
        the transfer functions, each "of order n" for every n of ``poles`` (:func:`black_box_orders`), on the
        same estimation data and scored on the same validation data (``offsets`` output / estimate: the
        estimation part's means removed).
    nk : int
        Input delay of the black-box models, samples.
    tf : bool
        Also the continuous-time transfer functions (the grey-box rows).
    share : float
        Share of ``data`` that estimates when no ``validation`` run is given (default 2/3).

    Returns
    -------
    OrderTable
    """
    from ehas_env.identification.fit import fit_percent, tfest

    if validation is None:
        est_data, k0 = split(data, share)
        val_y, val_src = data.y[k0:], f"last {data.n - k0} samples of {data.source}"
    else:
        est_data, k0 = data, 0
        val_y, val_src = validation.y, validation.source
    rows = []
    for n in poles:
        for m in range(n if tf else 0):
            est = tfest(est_data, n_poles=n, n_zeros=m, intersample=intersample, delay=delay, offsets=offsets,
                        max_delay_s=max_delay_s)
            p = n_parameters(est)
            if validation is None:
                y_all = est.simulate(data.t, data.u)
                y_val = y_all[k0:]
            else:
                y_val = est.simulate(validation.t, validation.u)
            e_crit = {"fit_percent": float(est.fit_percent), **criteria(est.residuals, p)}
            v_crit = {"fit_percent": float(fit_percent(val_y, y_val)), **criteria(val_y - y_val, p)}
            if predict_k:
                c = fit_ar(est.residuals)
                if validation is None:
                    yp = y_all + predict_residual(data.y - y_all, c, predict_k)
                    yp = yp[k0:]
                else:
                    yp = y_val + predict_residual(val_y - y_val, c, predict_k)
                v_crit["predict_fit_percent"] = float(fit_percent(val_y, yp))
                e_crit["predict_fit_percent"] = float(fit_percent(est_data.y, predict(est, predict_k, ar=c)))
            rows.append(OrderRow(poles=n, zeros=m, p=p, estimation=e_crit, validation=v_crit, est=est, y_val=y_val,
                                 usable=est.usable() and bool(np.all(np.isfinite(y_val)))))
        for structure in black_box:
            rows.append(_black_box_row(structure, n, nk, est_data, data, validation, k0, offsets, predict_k, val_y))
    if not rows:
        raise ValueError("order_table: no structure to compare (tf=False and no black_box)")
    chosen = choose(rows)
    return OrderTable(rows=rows, chosen=chosen, validation_source=val_src, n_estimation=est_data.n,
                      n_validation=int(np.size(val_y)), predict_k=predict_k)
