"""No motion on a limp joint (issue 35, finding 4): the one check every verb that starts a
motion runs before it starts anything.

A joint is limp when its servo is offline (no replies), refused (kept offline: old firmware) or
has torque off (by a command, or its own alarm shutdown). A walk, a page, ball play, a
choreography or the policy loop on a limp leg would carry the body on a joint that does not
hold it: refused, in one line naming the servo and the fix. A joint that goes limp while a
motion drives it stops that motion (``MotionManager.stop_limp``).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from schemas.errors import ErrorCode, Reject

if TYPE_CHECKING:
    from robot_daemon.arbiter.registry import MotionContext


def limp_reason(ctx: MotionContext, jid: int) -> str | None:
    """Why joint ``jid`` cannot take part in a motion now (None: it can)."""
    frame = ctx.frame
    if frame is None:
        return None
    refused: dict[int, str] = getattr(ctx.bus, "refused", {}) or {}
    if jid in refused:  # the scan's one line, "servo 7 (r_hip_yaw) has MX-28 firmware …"
        text = refused[jid]
        prefix = f"servo {jid} ({ctx.robot.by_id[jid].name}) "
        return text[len(prefix):] if text.startswith(prefix) else text
    if not frame.online[jid]:
        return "is offline: not moved (check its cable; see status.bus.offline)"
    if not frame.torque_enabled[jid]:
        return "has torque off: enable it first (`torque` enable=true)"
    return None


def refuse_limp(
    ctx: MotionContext, ids: Iterable[int], what: str, field: str | None = None
) -> None:
    """``Reject`` (unavailable) naming the first limp joint of ``ids``, before ``what`` starts."""
    for jid in sorted(set(ids)):
        why = limp_reason(ctx, jid)
        if why is not None:
            name = ctx.robot.by_id[jid].name
            message = f"{what} refused: servo {jid} ({name}) {why}"
            raise Reject(ErrorCode.UNAVAILABLE, message, field)
