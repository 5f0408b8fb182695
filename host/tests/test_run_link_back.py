"""`agnav run` with the firmware's own layers: after a link loss the firmware holds its goal and
follow-wall layers until a fresh command (docs/safety.md "Failsafe hold"), so the run notices the link
coming back and sends its goal again."""

from __future__ import annotations

from types import SimpleNamespace

from agnav_host.cli import run as run_command
from agnav_host.link.state import BehaviourState


def _state(t: float, layer: int, reason: int) -> SimpleNamespace:
    return SimpleNamespace(behaviour=BehaviourState(t, layer, reason, 0, 0.0, 0.0, t), pose=None)


def test_link_back_is_seen_once_after_a_link_loss_and_not_after_other_failsafes():
    back = run_command._LinkBack()
    seq = [(1.0, 6, 13), (1.5, 1, 2), (1.6, 1, 2), (2.0, 0, 15), (2.2, 0, 15), (3.0, 1, 1), (3.5, 0, 15)]
    seen = [back(_state(t, layer, reason)) for t, layer, reason in seq]
    assert seen == [False, False, False, True, False, False, False]
    assert back(_state(2.0, 0, 15)) is False  # the same status read again


def test_the_goal_is_sent_again_and_seeking_must_be_seen_again():
    sent = []
    robot = SimpleNamespace(set_goal=lambda x, y: sent.append((x, y)))
    g = run_command._FirmwareGoal(robot, 8.0, 0.0, 0.1)
    assert sent == [(8.0, 0.0)]
    g.reached(_state(g.sent_s + 1.0, 6, 13), g.sent_s + 1.0)
    assert g.seeking
    g.again(g.sent_s + 5.0)
    assert sent == [(8.0, 0.0), (8.0, 0.0)] and not g.seeking
