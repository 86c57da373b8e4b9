"""A Foxglove WebSocket protocol client for tests, on the general `websockets` library.

It speaks the protocol as documented (foxglove/ws-protocol docs/spec.md): JSON text ops and
binary frames with a 1-byte opcode and little-endian integers. foxglove-sdk's server names the
protocol ``foxglove.sdk.v1`` (and refuses any other subprotocol), so both names are offered.
Protobuf payloads are decoded with the FileDescriptorSet each channel advertises.
"""

from __future__ import annotations

import base64
import json
import struct
import time
from dataclasses import dataclass, field
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from websockets.sync.client import ClientConnection, connect

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
MESSAGE_DATA, SERVICE_RESPONSE = 0x01, 0x03
CLIENT_MESSAGE_DATA, SERVICE_REQUEST = 0x01, 0x02
WAIT = 20.0


@dataclass
class Received:
    topic: str
    log_time: int
    payload: bytes
    decoded: Any = None


@dataclass
class FoxgloveClient:
    ws: ClientConnection
    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[int, dict[str, Any]] = field(default_factory=dict)  # id → advertisement
    services: dict[str, dict[str, Any]] = field(default_factory=dict)  # name → advertisement
    statuses: list[dict[str, Any]] = field(default_factory=list)
    texts: list[dict[str, Any]] = field(default_factory=list)
    subs: dict[int, int] = field(default_factory=dict)  # subscription id → channel id
    pending: list[Received] = field(default_factory=list)
    responses: dict[int, tuple[str, Any]] = field(default_factory=dict)  # call id → ok/fail
    _next_sub: int = 0
    _classes: dict[int, Any] = field(default_factory=dict)

    @classmethod
    def open(cls, url: str) -> FoxgloveClient:
        # Entered as a context manager (closed by ``close()``): websockets warns otherwise.
        ws = connect(  # type: ignore[arg-type]
            url, subprotocols=SUBPROTOCOLS, max_size=None, ping_interval=None
        ).__enter__()
        client = cls(ws)
        client.until(lambda c: c.server_info and c.channels and c.services)
        return client

    def close(self) -> None:
        self.ws.close()

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- reading ------------------------------------------------------------------------------
    def pump(self, timeout: float) -> None:
        """Read one frame (or return after ``timeout``) and file it."""
        try:
            frame = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return
        if isinstance(frame, bytes):
            self._binary(frame)
        else:
            self._text(json.loads(frame))

    def until(self, predicate: Any, timeout: float = WAIT) -> Any:
        deadline = time.monotonic() + timeout
        while True:
            got = predicate(self)
            if got:
                return got
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"condition not met within {timeout} s; statuses {self.statuses}"
            self.pump(min(remaining, 0.5))

    def _text(self, msg: dict[str, Any]) -> None:
        self.texts.append(msg)
        op = msg.get("op")
        if op == "serverInfo":
            self.server_info = msg
        elif op == "advertise":
            for ch in msg["channels"]:
                self.channels[ch["id"]] = ch
        elif op == "advertiseServices":
            for s in msg["services"]:
                self.services[s["name"]] = s
        elif op == "status":
            self.statuses.append(msg)
        elif op == "serviceCallFailure":
            self.responses[msg["callId"]] = ("fail", msg["message"])

    def _binary(self, frame: bytes) -> None:
        if frame[0] == MESSAGE_DATA:
            sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
            channel = self.channels[self.subs[sub_id]]
            self.pending.append(Received(channel["topic"], log_time, frame[13:]))
        elif frame[0] == SERVICE_RESPONSE:
            _sid, call_id, n = struct.unpack_from("<III", frame, 1)
            self.responses[call_id] = ("ok", json.loads(frame[13 + n :]))

    # -- channels ------------------------------------------------------------------------------
    def channel(self, topic: str) -> dict[str, Any]:
        for ch in self.channels.values():
            if ch["topic"] == topic:
                return ch
        raise AssertionError(f"{topic} not advertised; channels: {self.topics()}")

    def topics(self) -> list[str]:
        return sorted(ch["topic"] for ch in self.channels.values())

    def subscribe(self, *topics: str) -> list[int]:
        subs = []
        for topic in topics:
            sid, self._next_sub = self._next_sub, self._next_sub + 1
            self.subs[sid] = self.channel(topic)["id"]
            subs.append({"id": sid, "channelId": self.subs[sid]})
        self.send({"op": "subscribe", "subscriptions": subs})
        return [s["id"] for s in subs]

    def unsubscribe(self, sub_ids: list[int]) -> None:
        self.send({"op": "unsubscribe", "subscriptionIds": sub_ids})

    def send(self, msg: dict[str, Any]) -> None:
        self.ws.send(json.dumps(msg))

    def decode(self, rec: Received) -> Any:
        ch = self.channel(rec.topic)
        if ch["encoding"] == "json":
            return json.loads(rec.payload)
        cls = self._classes.get(ch["id"])
        if cls is None:
            fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(ch["schema"]))
            pool = descriptor_pool.DescriptorPool()
            for f in fds.file:
                pool.Add(f)
            cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(ch["schemaName"]))
            self._classes[ch["id"]] = cls
        return cls.FromString(rec.payload)

    def take(self, topic: str, predicate: Any = lambda m: True, timeout: float = WAIT) -> Any:
        """The next decoded message on ``topic`` satisfying ``predicate`` (older ones on that
        topic are dropped)."""

        def find(c: FoxgloveClient) -> Any:
            while True:
                i = next((i for i, r in enumerate(c.pending) if r.topic == topic), None)
                if i is None:
                    return None
                rec = c.pending.pop(i)
                rec.decoded = c.decode(rec)
                if predicate(rec.decoded):
                    return rec

        return self.until(find, timeout).decoded

    def drop(self, topic: str) -> None:
        self.pending = [r for r in self.pending if r.topic != topic]

    # -- services, parameters, client publish ------------------------------------------------------
    def call(self, service: str, request: dict[str, Any] | bytes, call_id: int) -> tuple[str, Any]:
        sid = self.services[service]["id"]
        payload = request if isinstance(request, bytes) else json.dumps(request).encode()
        enc = b"json"
        head = bytes([SERVICE_REQUEST]) + struct.pack("<III", sid, call_id, len(enc))
        self.ws.send(head + enc + payload)
        return self.until(lambda c: c.responses.get(call_id))

    def advertise(self, channel_id: int, topic: str, schema_name: str) -> None:
        self.send(
            {
                "op": "advertise",
                "channels": [
                    {
                        "id": channel_id,
                        "topic": topic,
                        "encoding": "json",
                        "schemaName": schema_name,
                    }
                ],
            }
        )

    def publish(self, channel_id: int, msg: dict[str, Any]) -> None:
        self.ws.send(
            bytes([CLIENT_MESSAGE_DATA]) + struct.pack("<I", channel_id) + json.dumps(msg).encode()
        )

    def get_parameters(self, names: list[str], req_id: str) -> list[dict[str, Any]]:
        self.send({"op": "getParameters", "parameterNames": names, "id": req_id})
        return self._parameter_values(req_id)

    def set_parameters(self, params: list[dict[str, Any]], req_id: str) -> list[dict[str, Any]]:
        self.send({"op": "setParameters", "parameters": params, "id": req_id})
        return self._parameter_values(req_id)

    def _parameter_values(self, req_id: str) -> list[dict[str, Any]]:
        """The parameters of the server's ``parameterValues`` answer to request ``req_id``."""
        reply = self.until(
            lambda c: next(
                (t for t in c.texts if t.get("op") == "parameterValues" and t.get("id") == req_id),
                None,
            )
        )
        return reply["parameters"]

    def status_matching(self, text: str) -> dict[str, Any]:
        return self.until(lambda c: next((s for s in c.statuses if text in s["message"]), None))
