"""navzoo.torch_threads.one_torch_thread, and the evaluations that run under it."""

from __future__ import annotations

import pytest
import torch

from navzoo.torch_threads import one_torch_thread


@pytest.fixture
def two_threads():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(before)


def test_one_thread_inside_and_the_callers_back_even_after_an_error(two_threads):
    with one_torch_thread():
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2
    with pytest.raises(RuntimeError, match="boom"), one_torch_thread():
        raise RuntimeError("boom")
    assert torch.get_num_threads() == 2


def test_the_path_task_check_runs_on_one_thread(two_threads, monkeypatch):
    from navzoo.agents.amp import evaluate as ev

    seen = []
    monkeypatch.setattr(ev, "_evaluate", lambda *a: seen.append(torch.get_num_threads()) or {"falls": 0})
    assert ev.evaluate("any", envs=2, seconds=0.1) == {"falls": 0}
    assert seen == [1] and torch.get_num_threads() == 2
