"""Figures of simulated or measured runs (matplotlib, Agg backend)."""
from __future__ import annotations

from pathlib import Path


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_run(res, path, title: str | None = None) -> Path:
    """Position/reference, error, current, pressures and load of one run, saved to ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
    ax[0].plot(res.t, res.theta_deg, label="theta (LVDT)")
    if res.theta_ref_deg is not None:
        ax[0].plot(res.t, res.theta_ref_deg, "--", label="theta_ref")
        ax0b = ax[0].twinx()
        ax0b.plot(res.t, res.theta_ref_deg - res.theta_deg, color="C3", lw=0.8)
        ax0b.set_ylabel("error, deg", color="C3")
    ax[0].set_ylabel("angle, deg")
    ax[0].legend(loc="upper left")
    ax[1].plot(res.t, res.current_mA)
    ax[1].set_ylabel("current, mA")
    ax[2].plot(res.t, res.p_a_bar, label="P_A")
    ax[2].plot(res.t, res.p_b_bar, label="P_B")
    ax[2].plot(res.t, res.p_s_bar, label="P_s")
    ax[2].set_ylabel("pressure, bar")
    ax[2].legend(loc="upper left")
    ax[3].plot(res.t, res.load_kN)
    ax[3].set_ylabel("load, kN")
    ax[3].set_xlabel("t, s")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def save_figure(fig, path, dpi: int = 90) -> Path:
    """Render ``fig`` to PNG in memory and write it atomically (no half-written or stray temporary file)."""
    import io

    from ehas_env.output.files import atomic_write_bytes

    plt = _pyplot()
    buf = io.BytesIO()
    try:
        fig.savefig(buf, dpi=dpi, format=Path(path).suffix.lstrip(".") or "png")
    finally:
        plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())
