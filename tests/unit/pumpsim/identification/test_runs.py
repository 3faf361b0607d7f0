"""Model runs remembered across problems (runs.MODEL_RUNS): the same inputs by value give the
remembered run as a copy, any changed input runs again, and only the last few are kept."""
import numpy as np

from pumpsim.identification.runs import RUN_SAMPLES, RunMemo


def test_a_run_is_remembered_by_its_inputs_values_and_comes_back_as_a_copy():
    memo, calls = RunMemo(size=2), []

    def run(theta):
        calls.append(1)
        return (np.sin(theta), np.cos(theta))

    theta, tau = np.linspace(0, 1, 50), np.arange(50.0)
    first = memo.get(("torque", "lib", 1, b"z"), (theta, tau), lambda: run(theta))
    first[0][:] = 0.0  # the caller writes into its copy
    again = memo.get(("torque", "lib", 1, b"z"), (theta.copy(), tau.copy()), lambda: run(theta))
    assert len(calls) == 1
    np.testing.assert_array_equal(again[0], np.sin(theta))
    memo.get(("torque", "lib", 1, b"z"), (theta + 1e-12, tau), lambda: run(theta + 1e-12))  # another angle
    memo.get(("torque", "lib", 2, b"z"), (theta, tau), lambda: run(theta))  # another order
    assert len(calls) == 3
    memo.get(("torque", "lib", 1, b"z"), (theta, tau), lambda: run(theta))  # pushed out by the two
    assert len(calls) == 4 and len(memo.entries) == 2


def test_a_long_run_is_not_kept():
    memo = RunMemo()
    theta = np.zeros(RUN_SAMPLES + 1)
    memo.get(("torque",), (theta,), lambda: (theta + 1.0,))
    assert memo.entries == []
