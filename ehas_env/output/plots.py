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
    fig, ax = plt.subplots(4, 1, figsize=(9, 9.5), sharex=True)
    above = dict(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3, fontsize=8, frameon=False, borderaxespad=0.1)
    h = ax[0].plot(res.t, res.theta_deg, label="theta, measured (LVDT)")
    if res.theta_ref_deg is not None:
        h += ax[0].plot(res.t, res.theta_ref_deg, "--", label="theta_ref, reference")
        ax0b = ax[0].twinx()
        h += ax0b.plot(res.t, res.theta_ref_deg - res.theta_deg, color="C3", lw=0.8, label="error theta_ref - theta (right axis)")
        ax0b.set_ylabel("error, deg", color="C3")
    ax[0].set_ylabel("angle, deg")
    ax[0].legend(handles=h, **above)
    ax[1].plot(res.t, res.current_mA, label="valve current")
    ax[1].set_ylabel("current, mA")
    ax[1].legend(**above)
    ax[2].plot(res.t, res.p_a_bar, label="P_A (chamber A)")
    ax[2].plot(res.t, res.p_b_bar, label="P_B (chamber B)")
    ax[2].plot(res.t, res.p_s_bar, label="P_s (supply)")
    ax[2].set_ylabel("pressure, bar")
    ax[2].legend(**above)
    ax[3].plot(res.t, res.load_kN, label="actuator load A (P_A - P_B)")
    ax[3].set_ylabel("load, kN")
    ax[3].set_xlabel("t, s")
    ax[3].legend(**above)
    for a in ax:
        a.grid(True, alpha=0.3)
    if title:
        import textwrap

        fig.suptitle("\n".join(textwrap.wrap(title, 95)), fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def _titles(fig) -> list:
    """(text artist, room in pixels) of the figure's title and each axes' titles that have words."""
    out = []
    sup = getattr(fig, "_suptitle", None)
    if sup is not None and sup.get_text():
        out.append((sup, 0.98 * fig.bbox.width))
    for ax in fig.axes:
        for t in (ax.title, getattr(ax, "_left_title", None), getattr(ax, "_right_title", None)):
            if t is not None and t.get_text() and t.get_visible():
                out.append((t, min(1.1 * ax.bbox.width, 0.98 * fig.bbox.width)))
    return out


def fit_titles(fig) -> bool:
    """Wrap every title wider than its room (the figure's width; an axes' title: its axes' width) onto more lines.

    A title wider than the figure is cut at both sides in the saved image; one wider than its axes runs into
    its neighbour's.  Lines are broken at spaces, as many words per line as fit.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure (drawn once to measure its texts).

    Returns
    -------
    bool
        True when a title was wrapped (the caller lays the figure out again).
    """
    import textwrap

    wrapped = False
    for _ in range(3):
        renderer = fig.canvas.get_renderer()
        changed = False
        for t, room in _titles(fig):
            width = t.get_window_extent(renderer).width
            if width <= room:
                continue
            lines = t.get_text().split("\n")
            chars = max(12, int(max(map(len, lines)) * room / width))
            text = "\n".join(textwrap.fill(line, chars) for line in lines)
            if text != t.get_text():
                t.set_text(text)
                changed = wrapped = True
        if not changed:
            break
    return wrapped


def save_figure(fig, path, dpi: int = 90, metadata: dict | None = None) -> Path:
    """Render ``fig`` to PNG in memory and write it atomically (no half-written or stray temporary file).

    ``metadata`` (PNG text chunks, e.g. ``{"Description": ...}``) records what the figure states, readable
    without the image (a test reads a verdict figure's number back from it).  The figure is laid out
    (``tight_layout``) at ``dpi``, a title wider than its room wrapped (:func:`fit_titles`) and the figure
    laid out again, unless it placed its axes itself (``fig._ehas_layout``), so that no label or title is cut.
    """
    import io

    from ehas_env.output.files import atomic_write_bytes

    plt = _pyplot()
    buf = io.BytesIO()
    try:
        # lay the figure out at the resolution it is saved at: a font's width does not scale with the dpi
        # (at 90 dpi a 7 pt label is wider, relative to the figure, than at the default 100), so a layout made
        # at another dpi cuts the longest labels
        fig.set_dpi(dpi)
        manual = getattr(fig, "_ehas_layout", False)
        if not manual:
            fig.tight_layout()
        if fit_titles(fig) and not manual:
            fig.tight_layout()
        fig.savefig(buf, dpi=dpi, format=Path(path).suffix.lstrip(".") or "png", metadata=metadata)
    finally:
        plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())
