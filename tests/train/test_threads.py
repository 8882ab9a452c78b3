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


def test_one_thread_gives_the_same_forward_as_two():
    """Inference of a small MLP: the same numbers on one thread as on two (what lets the
    policies evaluate on one without moving an evaluation's figures)."""
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(62, 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, 3))
    x = torch.linspace(-1.0, 1.0, 62 * 5).reshape(5, 62)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with torch.no_grad():
            two = net(x)
            with torch_threads(1):
                one = net(x)
        assert torch.equal(one, two)
    finally:
        torch.set_num_threads(before)
