"""A Protocol 1.0 bulk read that works with the pinned dynamixel-sdk.

dynamixel-sdk 3.8.4 … 4.1.0 cannot bulk-read on Protocol 1.0: ``GroupBulkRead.txPacket()``
calls ``Protocol1PacketHandler.bulkReadTx(port, param, param_length, False)``, one argument more
than that method takes, so it raises ``TypeError`` before sending anything. :class:`BulkRead`
sends the same packet through ``bulkReadTx(port, param, param_length)`` and keeps the SDK's
receive path (``readRx`` per device, in parameter order) and its data access (``getData``).

    reader = BulkRead(port, packet_handler)
    for dxl_id in SERVO_IDS:
        reader.addParam(dxl_id, SERVO_BULK_START, SERVO_BULK_LENGTH)
    if reader.txRxPacket() == COMM_SUCCESS:
        position = reader.getData(1, MX28.PRESENT_POSITION.reg.address, 2)

As in the SDK, one silent or corrupt device fails the whole transaction (the result code says
how); :meth:`BulkRead.read` returns what did arrive before it, by ID.
"""

from __future__ import annotations

from dynamixel_sdk import COMM_NOT_AVAILABLE, COMM_SUCCESS, GroupBulkRead
from dynamixel_sdk.group_bulk_read import PARAM_NUM_DATA, PARAM_NUM_LENGTH


class BulkRead(GroupBulkRead):  # type: ignore[misc]  # dynamixel-sdk ships no types
    def txPacket(self) -> int:
        if not self.data_dict:
            return int(COMM_NOT_AVAILABLE)
        if self.is_param_changed or not self.param:
            self.makeParam()
        if self.ph.getProtocolVersion() != 1.0:
            sent: int = super().txPacket()
        else:
            sent = self.ph.bulkReadTx(self.port, self.param, len(self.data_dict) * 3)
        return sent

    def read(self) -> tuple[int, dict[int, bytes], dict[int, int]]:
        """One transaction: (result code, data by ID, error bits by ID) for the devices that
        answered before the first failure (all of them when the result is ``COMM_SUCCESS``)."""
        self.last_result = False
        result = self.txPacket()
        data: dict[int, bytes] = {}
        errors: dict[int, int] = {}
        if result != COMM_SUCCESS:
            return result, data, errors
        for dxl_id, entry in self.data_dict.items():
            entry[PARAM_NUM_DATA], result, error = self.ph.readRx(
                self.port, dxl_id, entry[PARAM_NUM_LENGTH]
            )
            if result != COMM_SUCCESS:
                return result, data, errors
            data[dxl_id] = bytes(entry[PARAM_NUM_DATA])
            errors[dxl_id] = error
        self.last_result = True
        return result, data, errors
