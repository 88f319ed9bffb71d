"""The subproblem builders take their state count from the layout: the time-domain subproblem
builds on the 8-state model (angle of attack and bank as states) as on the 7-state one."""

from __future__ import annotations

import numpy as np

from worker.solver.models.layout import ALPHA_BANK_STATE
from worker.solver.transcription.foh_data import SubproblemData
from worker.solver.transcription.foh_exact import IntervalMaps
from worker.solver.transcription.foh_subproblem import FohSubproblem
from worker.solver.transcription.terminal import TerminalRow


def test_foh_subproblem_on_eight_states() -> None:
    K, N, nz = 5, 4, ALPHA_BANK_STATE.size
    rng = np.random.default_rng(3)
    scale = rng.uniform(0.5, 2.0, nz)
    sub = FohSubproblem(
        K,
        state_scale=scale,
        rate_scale=0.5,
        interval_scale=0.1,
        n_initial=6,
        terminal=[TerminalRow(3, "soft", value=0.9, weight=1.0)],
        bank_max=1.2,
        bank_rate_max=0.2,
        n_limits=1,
        n_zones=0,
        grid=None,
        weight_trust_region=1.0,
        weight_trust_interval=0.0,
        identity_e=True,
        layout=ALPHA_BANK_STATE,
    )
    phi = rng.normal(size=(N, nz, nz))
    maps = IntervalMaps(
        Phi=phi,
        Bm=rng.normal(size=(N, nz)),
        Bp=rng.normal(size=(N, nz)),
        S=rng.normal(size=(N, nz)),
        x_prop=rng.normal(size=(N, nz)),
    )
    z = rng.normal(size=(K, nz))
    zeros = np.zeros((K, 1))
    data = SubproblemData(
        z=z,
        w=np.zeros(K),
        s=np.full(N, 0.1),
        maps=maps,
        initial=z[0, :6],
        path_g=zeros,
        path_gr=zeros,
        path_gv=zeros,
        zone_c=np.zeros((0, K)),
        zone_clat=np.zeros((0, K)),
        zone_clon=np.zeros((0, K)),
        grad_z=np.zeros((K, nz)),
        grad_s=np.zeros(N),
        quad_z=np.zeros((K, nz)),
        quad_center=np.zeros((K, nz)),
    )
    problem = sub.build(data)
    problem.validate()
    assert sub.rows.rows("dynamics") == slice(0, N * nz)
    A = problem.A.toarray()
    k, i = 2, 7  # the angle-of-attack row of interval 2
    row = nz * k + i
    assert A[row, sub.col_z[k + 1, i]] == 1.0
    np.testing.assert_allclose(A[row, sub.col_z[k]], -phi[k, i] * scale / scale[i], rtol=1e-15)
    bank = sub.rows.start("bank")  # the bank is still found by name (index 6 of 8)
    assert A[bank, sub.col_z[0, 6]] == scale[6]
    solution = sub.unpack(np.zeros(sub.n), data)
    assert solution.z.shape == (K, nz)
