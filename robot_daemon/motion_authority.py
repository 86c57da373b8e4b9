"""Who may move the robot: the motion-authority rule, written once (issue 35).

The robot moves only

(a) to **hold** where it is: the motion manager writes the last goal of a torqued joint nobody
    drives (after a halt, a motion's end, a lost port's return, start-up), never a new one;
(b) in a motion a **client** started and that client's lease still covers: every verb that
    moves the robot needs the lease (``schemas.commands``), and whenever the lease ends the
    motion it started comes to a safe stop (``MotionManager.stop_all``);
(c) in a **protective action** listed in :data:`MOVES_BY_ITSELF` below, each with the setting
    that turns it off.

Anything else that could move the robot (a fall detected with nobody's motion running, the
servo power or the serial port coming back, the daemon starting) holds or stays limp and says
so in one event. :data:`MOVES_BY_ITSELF` is the complete list of what the robot does without a
command; ``docs/first-session.md`` shows it (rendered by ``scripts/reference.py``, compared by
``tests/unit/test_docs.py``), and every entry names the module that does it, which
``tests/unit/test_motion_authority.py`` checks refers back to the entry by its name.

A base module: data only, imported by the motion modules and the engine alike.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SelfMove:
    """One thing the robot does without a command of its own."""

    name: str  # the key the code that does it refers to (``MOVE_…`` constants below)
    what: str  # the move, as the owner sees it
    when: str  # what starts it
    off: str  # how to turn it off (or why it cannot be)
    where: str  # the module that does it


# Fall recovery: the motion modules a client drives under its lease during which a fall is
# followed by the get-up page (motion/fall.py). Not pages, poses or trajectories: a client
# driving joints itself decides what comes after a fall.
RECOVERS_FROM_FALLS = ("walking", "ball", "choreography", "policy")
RECOVERS_FROM_FALLS_WORDS = "walk, ball play, behaviour or policy loop"

MOVE_HOLD = "hold"
MOVE_WALK_LAST_STEP = "walk_last_step"
MOVE_FALL_RECOVERY = "fall_recovery"
MOVE_LIMP_JOINT_STOP = "limp_joint_stop"
MOVE_POWER_SIT = "power_sit"
MOVE_POWER_OFF = "power_off"
MOVE_SERVO_SHUTDOWN = "servo_shutdown"
MOVE_START_TORQUE = "start_torque"
MOVE_POWER_LOST = "power_lost"
MOVE_POWER_BACK = "power_back"
MOVE_MODE_BUTTON = "mode_button"
MOVE_SECOND_MASTER = "second_master"

MOVES_BY_ITSELF: tuple[SelfMove, ...] = (
    SelfMove(
        MOVE_HOLD,
        "holds the last goal of every torqued joint nobody drives (a sagging joint is pushed "
        "back to it; nothing new is commanded)",
        "a halt, the end of a motion or of the lease, the serial port's return, start-up",
        "`torque` enable=false makes the joints limp instead",
        "robot_daemon/motion/manager.py",
    ),
    SelfMove(
        MOVE_WALK_LAST_STEP,
        "a walk ends its step: to the next double support after `halt` or a stop of the daemon "
        "(at most half a gait period), the current step and at most one more after `walk` "
        "op=stop or the lease's end",
        "`halt`, the daemon stopping (SIGTERM, Ctrl-C), `walk` op=stop, the lease ending, a limp "
        "driven joint",
        "none: stopped mid-step the robot stands on one foot and falls; `torque` "
        "enable=false or the reset button go limp at once",
        "robot_daemon/motion/walking/gait.py",
    ),
    SelfMove(
        MOVE_FALL_RECOVERY,
        "plays the get-up page (10 from the front, 11 from the back) after a fall",
        "a fall during a walk, ball play, a behaviour or the policy loop that a lease holder "
        "started, while the lease is held; never after a halt, a power or port event or "
        "start-up, nor with nobody's motion running (then it lies still and says so)",
        "`[fall] recover = false` (config/motion.toml)",
        "robot_daemon/motion/fall.py",
    ),
    SelfMove(
        MOVE_LIMP_JOINT_STOP,
        "a motion stops safely (a walk at its next double support, the rest holding) when a "
        "joint it drives goes offline, into alarm or torque off",
        "a driven servo's alarm shutdown, missed replies, a `torque` off",
        "none: a motion on a limp joint is what it prevents",
        "robot_daemon/motion/manager.py",
    ),
    SelfMove(
        MOVE_POWER_SIT,
        "stops every motion, plays the sit-down page and limits the torque",
        "the battery or a servo's temperature at the `sit` level of the power/heat policy",
        "`[power]`/`[heat]` `enabled = false` or their thresholds (config/power.toml)",
        "robot_daemon/engine/power_actions.py",
    ),
    SelfMove(
        MOVE_POWER_OFF,
        "turns torque off (every servo for the battery, the hot servo for heat): the robot "
        "goes limp",
        "the battery or a servo's temperature at the `off` level of the power/heat policy",
        "`[power]`/`[heat]` `enabled = false` or their thresholds (config/power.toml)",
        "robot_daemon/engine/power_actions.py",
    ),
    SelfMove(
        MOVE_SERVO_SHUTDOWN,
        "a servo in overheating or overload alarm goes limp, as its firmware's alarm shutdown "
        "does; torque comes back only with a `torque` command",
        "a servo's overheating or overload alarm bit",
        "none: the servo's own firmware does it too",
        "robot_daemon/bus/sensor_read.py",
    ),
    SelfMove(
        MOVE_START_TORQUE,
        "powers the servo bus and turns torque on every servo that answers and is not in alarm "
        "shutdown, each holding where it is (a servo found torqued keeps its goal only within "
        "5° of where it is; one in alarm is left limp and reported)",
        "the daemon starting (the boot service at power-on, a restart); never after the reset "
        "button or a lost port",
        "`[daemon] torque_on_start = false` (torque stays as found); `[bus] "
        "hold_sag_limit_deg`",
        "robot_daemon/engine/bus_lifecycle.py",
    ),
    SelfMove(
        MOVE_POWER_LOST,
        "every motion halts and the robot goes limp (the servos have no power); they stay off "
        "until someone powers them (`power` op=on, START, the TUI)",
        "the CM-730 reading DXL power off: its reset button, a brown-out, `power` op=off",
        "none: without power the servos cannot hold",
        "robot_daemon/engine/bus_lifecycle.py",
    ),
    SelfMove(
        MOVE_POWER_BACK,
        "powers the servos and gives torque back to those that had it, each holding where it "
        "is (nothing else moves; the others stay limp)",
        "a press of the START button while the servos are off (as `power` op=on would)",
        "`[daemon.buttons] start = \"none\"`",
        "robot_daemon/engine/bus_lifecycle.py",
    ),
    SelfMove(
        MOVE_MODE_BUTTON,
        "every motion stops safely (a walk at its next double support) and the pose is held; "
        "with `sit`, the sit-down page plays",
        "a press of the MODE button",
        "`[daemon.buttons] mode = \"none\"`",
        "robot_daemon/engine/bus_lifecycle.py",
    ),
    SelfMove(
        MOVE_SECOND_MASTER,
        "every motion halts and holds; commands that move the robot are refused",
        "another process opening the serial port while the daemon runs",
        "`[daemon] holder_check_s = 0`",
        "robot_daemon/engine/bus_lifecycle.py",
    ),
)

BY_NAME = {m.name: m for m in MOVES_BY_ITSELF}


def render_moves() -> str:
    """The list as ``docs/first-session.md`` shows it (a Markdown table)."""
    rows = ["| what the robot does | when | turned off by |", "|---|---|---|"]
    rows += [f"| {m.what} | {m.when} | {m.off} |" for m in MOVES_BY_ITSELF]
    return "\n".join(rows)
