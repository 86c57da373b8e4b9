"""rmw_zenoh's wire format without ROS: the key space and liveliness tokens (``graph``), the
attachment with sequence numbers and GIDs (``attachment``), CDR and type hashes (``types``), and
the mapping between the daemon's messages and ROS messages (``convert``).

A library, not an adapter: the ROS 2 adapter (``clients.ros2``, ``darwin ros2``) and the
recorder's ``ros2`` profile (``clients.recording``) both import it; it imports neither.
``types`` and ``convert`` need the ``ros2`` extra (rosbags)."""

__all__ = ["attachment", "convert", "graph", "types"]
