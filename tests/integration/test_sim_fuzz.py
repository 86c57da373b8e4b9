"""Property over the real pty: garbage and broken packets from a client never stop the emulator,
and the dynamixel-sdk's next transaction is answered correctly."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings

from robot_daemon.bus.tables import CM730_ID, CM730_MODEL, MX28_MODEL
from robot_daemon.emulator import Emulator
from tests.fixtures.emulator import open_sdk
from tests.unit.test_sim_fuzz import line_noise


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(chunks=line_noise)
def test_garbage_on_the_pty_never_breaks_the_emulator(
    emulator: Emulator, chunks: list[bytes]
) -> None:
    port, ph = open_sdk(emulator.port, emulator=emulator)
    try:
        sent = emulator.stats["rx_bytes"]
        for chunk in chunks:
            port.writePort(chunk)
            sent += len(chunk)
        assert emulator.wait_stat("rx_bytes", sent)
        assert emulator.wait_quiet()
        # Random writes may have changed IDs, power or return levels: put them back first.
        with emulator.lock:
            emulator.bus.restore(power=True)
        assert ph.ping(port, CM730_ID)[:2] == (CM730_MODEL, 0)
        assert ph.ping(port, 1)[:2] == (MX28_MODEL, 0)
        assert ph.ping(port, 20)[:2] == (MX28_MODEL, 0)
    finally:
        port.closePort()
