"""The emulator's built-in control ops (served by :mod:`robot_daemon.emulator.control_service`).

| op | fields | does |
|---|---|---|
| `ops` | | lists the ops |
| `state` | | snapshot: time, power, LEDs, buttons, IMU, faults, stats, servos |
| `faults` | `drop`, `corrupt`, `delay` (0..1), `delay_ms`, `silent_ids` | sets reply faults |
| `clear_faults` | | no lost/corrupt/late replies, silent or hot servo, broken chain; 12 V |
| `restore` | | every device back to its defaults and IDs (power kept) |
| `silence` | `id`, `silent` (true) | a device stops (or resumes) answering |
| `overheat` | `id`, `on` (true), `celsius` | pins a servo above its limit (or at `celsius`) |
| `voltage` | `volts` | supply voltage |
| `body_motion` | `gyro` [x,y,z] rad/s, `accel` [x,y,z] m/s² | what the IMU feels (robot axes) |
| `button` | `name` (mode/start), `pressed` (true) | presses or releases a button |
| `set_position` | `id`, `rad` | moves a servo's horn from outside |
| `load` | `id`, `fraction` | external load on a servo (−1..1 of max torque) |
| `advance` | `dt` (s) | steps the dynamics now |
| `vanish` / `reappear` | | the serial port goes away / comes back (reply: `port`) |
| `chain` | `broken_after` [IDs] | cable breaks right after these servos ([] mends them) |
| `fresh_servo` | `id` | swaps that servo for a factory-fresh MX-28 (ID 1, 57,600 bps) |
| `set_id` | `id`, `new_id` | gives that servo another ID (one in use: two servos answer it) |
| `dxl_power_loss` | | DXL power goes (CM-730 reset button): servos silent until powered again |
| `cm730_late` | `reads` | the CM-730 ignores the next `reads` reads and bulk reads |
"""

from __future__ import annotations

from typing import Any

from robot_daemon.emulator import bringup
from robot_daemon.emulator.op_table import control_op, control_ops, field
from schemas.units import GRAVITY

Request = dict[str, Any]


@control_op("ops")
def _ops(emu, req: Request) -> dict[str, Any]:
    return {"ops": control_ops()}


@control_op("state")
def _state(emu, req: Request) -> dict[str, Any]:
    return emu.api.state()


@control_op("faults")
def _faults(emu, req: Request) -> dict[str, Any]:
    values = {
        name: field(req, name, float, None) for name in ("drop", "corrupt", "delay", "delay_ms")
    }
    silent = field(req, "silent_ids", list, None)
    if silent is not None:
        if not all(isinstance(i, int) and not isinstance(i, bool) for i in silent):
            raise ValueError(f"field 'silent_ids' must be a list of IDs, got {silent!r}")
        with emu.lock:
            for dxl_id in list(emu.bus.silent):
                emu.api.silence(dxl_id, False)
            for dxl_id in silent:
                emu.api.silence(dxl_id, True)
    emu.api.set_faults(**values)
    return emu.api.fault_state()


@control_op("clear_faults")
def _clear_faults(emu, req: Request) -> dict[str, Any]:
    with emu.lock:
        emu.api.set_faults(drop=0.0, corrupt=0.0, delay=0.0)
        for dxl_id in list(emu.bus.silent):
            emu.api.silence(dxl_id, False)
        for dxl_id, servo in emu.bus.servos.items():
            if servo.forced_temperature is not None:
                emu.api.overheat(dxl_id, False)
        emu.api.set_voltage(emu.settings.voltage)
        emu.bus.break_chain([])
        return emu.api.fault_state()


@control_op("restore")
def _restore(emu, req: Request) -> dict[str, Any]:
    with emu.lock:
        emu.bus.restore()
    return {}


@control_op("silence")
def _silence(emu, req: Request) -> dict[str, Any]:
    emu.api.silence(field(req, "id", int), field(req, "silent", bool, True))
    return emu.api.fault_state()


@control_op("overheat")
def _overheat(emu, req: Request) -> dict[str, Any]:
    celsius = req.get("celsius")
    if celsius is not None and not isinstance(celsius, int | float):
        raise ValueError(f"celsius must be a number, got {celsius!r}")
    emu.api.overheat(field(req, "id", int), field(req, "on", bool, True), celsius)
    return emu.api.fault_state()


@control_op("voltage")
def _voltage(emu, req: Request) -> dict[str, Any]:
    emu.api.set_voltage(field(req, "volts", float))
    return emu.api.fault_state()


@control_op("body_motion")
def _body_motion(emu, req: Request) -> dict[str, Any]:
    gyro = field(req, "gyro", list, [0.0, 0.0, 0.0])
    accel = field(req, "accel", list, [0.0, 0.0, GRAVITY])
    emu.api.set_body_motion(gyro, accel)
    return {"gyro": gyro, "accel": accel}


@control_op("button")
def _button(emu, req: Request) -> dict[str, Any]:
    emu.api.press_button(field(req, "name", str), field(req, "pressed", bool, True))
    return {"buttons": emu.api.register(emu.bus.cm730.id, "BUTTON")}


@control_op("set_position")
def _set_position(emu, req: Request) -> dict[str, Any]:
    emu.api.set_present_position(field(req, "id", int), field(req, "rad", float))
    return {}


@control_op("load")
def _load(emu, req: Request) -> dict[str, Any]:
    emu.api.set_external_load(field(req, "id", int), field(req, "fraction", float))
    return {}


@control_op("advance")
def _advance(emu, req: Request) -> dict[str, Any]:
    emu.advance(field(req, "dt", float))
    return {"sim_time": emu.sim_time}


@control_op("vanish")
def _vanish(emu, req: Request) -> dict[str, Any]:
    emu.vanish()
    return {}


@control_op("reappear")
def _reappear(emu, req: Request) -> dict[str, Any]:
    return {"port": emu.reappear()}


@control_op("chain")
def _chain(emu, req: Request) -> dict[str, Any]:
    after = field(req, "broken_after", list)
    if not all(isinstance(i, int) and not isinstance(i, bool) for i in after):
        raise ValueError(f"field 'broken_after' must be a list of servo IDs, got {after!r}")
    with emu.lock:
        emu.bus.break_chain(after)
    return emu.api.fault_state()


@control_op("fresh_servo")
def _fresh_servo(emu, req: Request) -> dict[str, Any]:
    with emu.lock:
        emu.bus.factory_fresh(field(req, "id", int))
    return emu.api.fault_state()


@control_op("set_id")
def _set_id(emu, req: Request) -> dict[str, Any]:
    dxl_id, new_id = field(req, "id", int), field(req, "new_id", int)
    with emu.lock:
        emu.bus.set_id(dxl_id, new_id)
    return {"id": dxl_id, "new_id": new_id}


@control_op("dxl_power_loss")
def _dxl_power_loss(emu, req: Request) -> dict[str, Any]:
    with emu.lock:
        bringup.dxl_power_loss(emu.bus)
    return {"power": False}


@control_op("cm730_late")
def _cm730_late(emu, req: Request) -> dict[str, Any]:
    reads = field(req, "reads", int)
    if reads < 0:
        raise ValueError(f"field 'reads' must be at least 0, not {reads}")
    with emu.lock:
        emu.bus.cm730_late_reads = reads
    return {"reads": reads}
