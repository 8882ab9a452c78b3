"""torch's intra-op threads around madsim's small networks (madsim.train.threads)."""

import pytest

torch = pytest.importorskip("torch", reason="needs the 'train' extra")

from madsim.train.threads import torch_threads  # noqa: E402


def test_the_block_runs_on_n_threads_and_the_callers_count_comes_back():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with torch_threads(1):
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError, match="inside"):
            with torch_threads(1):
                raise RuntimeError("inside")
        assert torch.get_num_threads() == 2              # restored on an exception too
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "1"])
def test_a_thread_count_that_is_not_a_positive_int_is_refused(bad):
    with pytest.raises(ValueError, match="torch threads"):
        with torch_threads(bad):
            pass


def test_the_block_computes_with_one_threads_bits_whatever_the_callers_count():
    """Inference of a small MLP inside `torch_threads(1)` from a caller on two threads gives
    exactly the numbers of a caller on one thread: policies evaluate with the same bits on any
    machine. (Whether two threads' numbers differ from one's depends on the CPU: equal on the
    Intel Xeon of sessions 1-10, different in the last bits on the AMD EPYC of session 11;
    pinning one thread is what makes the evaluation independent of it.)"""
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(62, 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, 3))
    x = torch.linspace(-1.0, 1.0, 62 * 5).reshape(5, 62)
    before = torch.get_num_threads()
    try:
        with torch.no_grad():
            torch.set_num_threads(1)
            plain = net(x)
            torch.set_num_threads(2)
            with torch_threads(1):
                pinned = net(x)
        assert torch.equal(pinned, plain)
    finally:
        torch.set_num_threads(before)
