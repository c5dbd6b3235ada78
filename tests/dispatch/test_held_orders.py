"""What beat's checks conclude from the order a robot's latest state holds (`dispatch.order_lacked`,
`dispatch.order_finished`): pure, no I/O."""

from datetime import UTC, datetime, timedelta

import pytest

from dispatch.held import ORDER_ECHO, HeldOrder, order_finished, order_lacked

SENT = datetime(2026, 11, 26, 12, 0, tzinfo=UTC)
LATER = SENT + ORDER_ECHO  # a state that arrived then would hold the order, had the robot got it
EARLY = LATER - timedelta(milliseconds=1)


@pytest.mark.parametrize(
    ("held", "lacked"),
    [
        pytest.param(None, False, id="no-state-yet"),
        pytest.param(HeldOrder("m-n0-r0", 0, True, None), False, id="arrival-not-recorded"),
        pytest.param(HeldOrder("other", 0, False, EARLY), False, id="may-have-left-before-the-order-arrived"),
        pytest.param(HeldOrder("other", 0, False, LATER), True, id="on-another-order"),
        pytest.param(HeldOrder("m-n0-r0", 0, True, LATER), True, id="on-an-older-update"),
        pytest.param(HeldOrder("m-n0-r0", 1, True, LATER), False, id="took-it"),
        pytest.param(HeldOrder("m-n0-r0", 2, False, LATER), False, id="took-a-later-update"),
    ],
)
def test_a_robot_lacks_its_order_only_on_evidence(held: HeldOrder | None, lacked: bool) -> None:
    assert order_lacked(held, order_id="m-n0-r0", update_id=1, sent_at=SENT) is lacked


def test_an_order_without_an_update_id_is_lacked_once_a_later_state_came() -> None:
    assert order_lacked(
        HeldOrder("m-n0-r0", 5, True, LATER), order_id="m-n0-r0", update_id=None, sent_at=SENT
    )


@pytest.mark.parametrize(
    ("held", "finished"),
    [
        pytest.param(None, False, id="no-state"),
        pytest.param(HeldOrder("m-n0-r0", 1, True, LATER), False, id="still-busy"),
        pytest.param(HeldOrder("m-n0-r0", 1, False, LATER), True, id="idle-at-its-end"),
        pytest.param(HeldOrder("m-n0-r0", 2, False, LATER), True, id="idle-after-a-later-update"),
        pytest.param(HeldOrder("m-n0-r0", 0, False, LATER), False, id="idle-on-an-older-update"),
        pytest.param(HeldOrder("other", 1, False, LATER), False, id="idle-on-another-order"),
    ],
)
def test_a_robot_finished_its_order_when_idle_at_its_end(held: HeldOrder | None, finished: bool) -> None:
    assert order_finished(held, order_id="m-n0-r0", update_id=1) is finished
