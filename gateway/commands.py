"""The gateway's ``darwin`` command, and the gateway as an adapter ``darwin up`` starts by
default, declared for :mod:`schemas.registry` (the launcher names no adapter)."""

from __future__ import annotations

from schemas.registry import Adapter, Command

COMMANDS = (
    Command(
        "gateway", "gateway.cli", "serve the legacy TCP JSON protocol to any number of clients", 100
    ),
)

ADAPTERS = (
    Adapter(
        "gateway",
        "do not start the gateway",
        10,
        default=True,
        listen_help="where legacy TCP clients connect (config gateway.listen)",
        listen_setting="gateway.listen",
        pass_role=True,
        pass_config=True,
    ),
)
