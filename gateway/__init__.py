"""The legacy TCP JSON gateway: the original DarwinServer protocol for any number of clients.

``framing`` (the wire format) and ``messages`` / ``translate`` / ``monitor`` / ``orchestrate``
(the protocol) are pure; ``hub``, ``connection`` and ``server`` do the I/O; ``cli`` is
``darwin gateway``.
"""
