"""Batch layout (guided self-scheduling) and the idle-time split of a study run (issue 14)."""
import math

import numpy as np
import pytest

from pumpsim import design
from pumpsim.design.execute import TAIL_TASK_SECONDS, TASK_SECONDS, guided_bounds
from pumpsim.design.store import read_manifest
from pumpsim.design.study import study_from_dict
from tests.conftest import EXAMPLES
from tests.tolerances import CLOCK_ABS

RIG = str(EXAMPLES / "test_rig.toml")


@pytest.mark.parametrize("n,per,workers", [(6000, 7e-4, 2), (10_000, 7e-4, 64), (37, 0.05, 2),
                                            (1, 1e-3, 4), (5000, 1e-5, 3)])
def test_guided_bounds_cover_every_design_once_and_shrink_to_the_tail(n, per, workers):
    b = np.asarray(guided_bounds(n, per, workers))
    sizes = np.diff(b)
    assert b[0] == 0 and b[-1] == n and (sizes > 0).all()
    big, small = math.ceil(TASK_SECONDS / per), math.ceil(TAIL_TASK_SECONDS / per)
    # never below the tail size (but for a study smaller than one), never more than half a worker's share
    assert (sizes[:-1] >= min(small, n)).all()
    assert sizes[0] <= max(math.ceil(n / (2 * workers)), big, small)
    # tasks of >= TASK_SECONDS while more than two per worker remain
    rem = n - b[:-1]
    assert (sizes[rem > 2 * workers * big] >= big).all()
    # the tail: the last batches are short, so the workers finish together
    if n * per > 4 * workers * TASK_SECONDS:
        assert sizes[-1] < 2 * small


def test_guided_layout_gives_the_same_table_resumes_and_splits_the_idle_time(tmp_path, monkeypatch):
    from pumpsim.design import execute

    # task lengths of a few designs, so that 40 designs make a guided layout of several batches
    monkeypatch.setattr(execute, "TASK_SECONDS", 4e-3)
    monkeypatch.setattr(execute, "TAIL_TASK_SECONDS", 1e-3)
    s = study_from_dict({"study": {"config": RIG, "sampler": "random", "samples": 40, "seed": 3},
                         "vary": {"vane.mass": {"distribution": "normal", "sd": 0.05, "relative": True}}})
    serial, _ = design.sweep(s, workers=0)
    out = tmp_path / "mc"
    two, st = design.sweep(s, out=out, workers=2, processes=False)
    assert two.equals(serial) and st.batches >= 4
    man = read_manifest(out)
    assert man["batch_bounds"][0] == 0 and man["batch_bounds"][-1] == 40 and man["batches"] == st.batches
    idle = st.idle_start + st.idle_between + st.idle_end
    assert idle == pytest.approx(st.workers * st.wall - st.compute, abs=CLOCK_ABS * st.batches)
    assert 0 < st.compute_cpu <= st.compute + CLOCK_ABS * st.batches  # a thread's CPU time <= its wall time
    # a resumed run takes the layout from the manifest: nothing is recomputed
    (out / "manifest.json").write_text((out / "manifest.json").read_text().replace('"complete"', '"running"'))
    again, st2 = design.sweep(s, out=out, workers=2, processes=False)
    assert st2.batches_skipped == st.batches and again.equals(serial)


def test_a_study_left_to_choose_runs_in_process_when_a_cluster_could_not_pay_for_its_start(monkeypatch):
    from pumpsim.design import cluster, execute

    started = []
    real = cluster.connect
    monkeypatch.setattr(execute, "connect", lambda *a: started.append(a) or real(None, 2, False))
    s = study_from_dict({"study": {"config": RIG, "sampler": "random", "samples": 40, "seed": 3},
                         "vary": {"vane.mass": {"distribution": "normal", "sd": 0.05, "relative": True}}})
    serial, _ = design.sweep(s, workers=0)
    df, st = design.sweep(s)  # 40 cheap designs: far below a cluster's start
    assert not started and st.workers == 1 and df.equals(serial)
    monkeypatch.setattr(execute, "worth_a_cluster", lambda cpu, workers: True)  # any study: a cluster
    df, st = design.sweep(s)
    assert len(started) == 1 and st.workers == 2 and df.equals(serial)


def test_a_cluster_is_worth_its_start_only_when_the_workers_make_up_for_it():
    from pumpsim.design.execute import IN_PROCESS_SECONDS, worth_a_cluster

    S = IN_PROCESS_SECONDS
    assert not worth_a_cluster(100 * S, 1)  # one worker process cannot beat this one
    # on 2 workers: S + T / 2 < T from T > 2 S; on 4: from T > 4 S / 3
    assert not worth_a_cluster(1.9 * S, 2) and worth_a_cluster(2.1 * S, 2)
    assert not worth_a_cluster(1.3 * S, 4) and worth_a_cluster(1.4 * S, 4)

