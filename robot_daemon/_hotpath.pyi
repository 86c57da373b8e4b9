# The optional C extension (robot_daemon/_hotpath.c); robot_daemon/hotpath.py loads it.
from collections.abc import Callable
from typing import Any

def configure_leg(
    ankle: float, leg: float, thigh2: float, calf2: float, two_thigh_calf: float, calf: float,
    thigh: float, pi: float, tau: float, fallback: Callable[..., Any], /,
) -> None: ...
def leg_ik_end_point(
    x: float, y: float, z: float, roll: float, pitch: float, yaw: float, /,
) -> tuple[float, float, float, float, float, float] | None: ...
def goals_raw(
    sign: list[float], offset: list[float], lo: list[float], hi: list[float], rads: list[float],
    k: float, c: int, /,
) -> Any: ...  # list[int], None, or NotImplemented
def pack_fields(
    head: bytes, keys: tuple[bytes, ...], values: list[Any], tail: bytes, /,
) -> Any: ...  # bytes, or NotImplemented
def packb(obj: Any, /) -> Any: ...  # bytes, or NotImplemented
def positions_list(
    raw: list[int], sign: list[float], offset: list[float], k: float, c: int, /,
) -> Any: ...  # list[float], or NotImplemented
def leg_servo_angles(
    end_point: Any, ids: tuple[int, ...], directions: tuple[int, ...], pitch_at: int,
    pitch_shift: float, /,
) -> Any: ...  # dict[int, float], None, or NotImplemented
def take_whole(
    buf: bytes, order: tuple[int, ...], lengths: tuple[int, ...], data: dict[int, bytes],
    errors: dict[int, int], /,
) -> Any: ...  # bool, or NotImplemented
def apply_fast(
    data: dict[int, bytes], fast: list[int], position: Any, speed: Any, load: Any, misses: Any,
    at_position: int, at_speed: int, at_load: int, width: int, /,
) -> Any: ...  # True, or NotImplemented
def joint_arrays(
    position: Any, speed: Any, load: Any, sign: Any, offset: Any, speed_table: Any,
    load_table: Any, k: float, c: int, out: Any, /,
) -> Any: ...  # True, or NotImplemented
def configure_walk(
    right_ids: tuple[int, ...], right_dirs: tuple[int, ...], left_ids: tuple[int, ...],
    left_dirs: tuple[int, ...], arm_deg_1: float, arm_deg_2: float,
    arm_rad_3_6: tuple[float, ...], feedback_signs: tuple[int, ...], deg_to_rad: float,
    unit: float, /,
) -> bool: ...
def walk_pose(
    walker: Any, params: Any, frame: Any, balance: bool,
    limits: dict[int, tuple[float, float]] | None, /,
) -> Any: ...  # (goals or None, [rl, fb] or None), or NotImplemented
def snapshot_lists(
    arrays: tuple[Any, ...], goal: Any, sign: list[float], offset: list[float], k: float, c: int,
    /,
) -> Any: ...  # tuple of lists, or NotImplemented
def configure_arrays(ndarray: type, samples: tuple[Any, ...], /) -> bool: ...
def take_run(
    buf: bytes, pos: int, due: int, order: tuple[int, ...], lengths: tuple[int, ...],
    data: dict[int, bytes], errors: dict[int, int], /,
) -> Any: ...  # (due, pos, good), or NotImplemented
def put_ints(
    array: Any, at: tuple[int, ...], values: list[int], /,
) -> Any: ...  # True, or NotImplemented
def put_row(
    arrays: tuple[Any, ...], j: int, values: tuple[Any, ...], /,
) -> Any: ...  # True, or NotImplemented
def imu_lists(
    gyro_raw: list[int], accel_raw: list[int], gyro_sign: tuple[int, ...],
    accel_sign: tuple[int, ...], c: int, f: float, pi: float, a: float, g: float, /,
) -> Any: ...  # (gyro, accel) lists, or NotImplemented
def imu_arrays(
    block: bytes, need: int, gyro_at: tuple[int, ...], accel_at: tuple[int, ...],
    gyro_sign: tuple[int, ...], accel_sign: tuple[int, ...], c: int, f: float, pi: float,
    a: float, g: float, gyro_raw: Any, accel_raw: Any, gyro: Any, accel: Any, /,
) -> Any: ...  # True, or NotImplemented
