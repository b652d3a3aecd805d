"""The public real-world record (DaISy hair dryer): its provenance check and a property published for it."""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.identification import real_data as RD


def test_the_stored_dryer_record_is_the_recorded_file(tmp_path):
    d = RD.load_dryer()
    assert d.n == 1000 and d.dt == RD.DT
    assert set(np.unique(d.u)) == {3.41, 6.41}  # the binary heater input
    bad = tmp_path / "dryer.dat"
    bad.write_bytes(RD.DATA.read_bytes().replace(b"6.41", b"6.42", 1))
    with pytest.raises(ValueError, match="SHA-256"):
        RD.load_dryer(bad)


def test_the_arx_delay_scan_finds_the_three_sample_delay_reported_for_this_record():
    """ControlSystemIdentification.jl's hair-dryer example reads a three-sample input delay off the impulse
    response of this same DaISy file; the ARX validation fit peaks there too."""
    d = RD.load_dryer()
    h = d.n // 2
    from ehas_env.identification.fit import IdData

    centred = IdData(t=d.t, u=d.u - d.u[:h].mean(), y=d.y - d.y[:h].mean(), dt=d.dt)
    scan = {k: v for k, v in RD.nk_scan(centred).items() if v is not None}
    assert max(scan, key=scan.get) == 3
