"""Conformance of clients.ros2's wire layer with rmw_zenoh (golden values from its sources).

Sources: rmw_zenoh_cpp ``liveliness_utils.cpp`` (token layout, mangling, ``qos_to_keyexpr``),
``attachment_helpers.cpp`` (attachment), ``rmw_publisher_data.cpp`` (sequence from 1),
``docs/design.md``; type hashes: rosidl-generated headers and the reference's table.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
import xxhash

from clients.rmw import graph
from clients.rmw.attachment import SIZE, Attachment, AttachmentError, Sequencer, gid_of
from clients.rmw.types import CdrError, dds_type, decode, encode, msg_class, type_hash

ZID = "8fa1c2d3e4f5061728394a5b6c7d8e9f"

HASHES = {
    "sensor_msgs/msg/JointState": "a13ee3a330e346c9d87b5aa18d24e116"
    "90752bd33a0350f11c5882bc9179260e",
    "sensor_msgs/msg/Imu": "7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    "sensor_msgs/msg/CompressedImage": "15640771531571185e2efc8a100baf92"
    "3961a4d15d5569652e6cb6691e8e371a",
    "geometry_msgs/msg/Twist": "9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
    "geometry_msgs/msg/TwistStamped": "5f0fcd4f81d5d06ad9b4c4c63e3ea51b"
    "82d6ae4d0558f1d475229b1121db6f64",
    "std_msgs/msg/String": "df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "tf2_msgs/msg/TFMessage": "e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    # std_srvs/Trigger as a Jazzy rmw_zenoh service key carries it (seen in a key expression
    # used against rmw_zenoh); rosbags alone gets services wrong (ServiceEventInfo's char[16]).
    "std_srvs/srv/Trigger": "eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f",
}


@pytest.mark.parametrize("ros_type", sorted(HASHES))
def test_type_hashes_equal_the_published_literals(ros_type):
    assert type_hash(ros_type) == "RIHS01_" + HASHES[ros_type]


def test_dds_type_names():
    assert dds_type("sensor_msgs/msg/JointState") == "sensor_msgs::msg::dds_::JointState_"
    assert dds_type("std_srvs/srv/SetBool") == "std_srvs::srv::dds_::SetBool_"


def test_data_key_expression():
    key = graph.data_key(
        0,
        "/op1/joint_states",
        dds_type("sensor_msgs/msg/JointState"),
        type_hash("sensor_msgs/msg/JointState"),
    )
    assert key == (
        "0/op1/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_"
        + HASHES["sensor_msgs/msg/JointState"]
    )
    assert graph.data_key(7, "/chatter/", "t", "h") == "7/chatter/t/h"  # strip_slashes: both ends


@pytest.mark.parametrize(
    ("qos", "text"),
    [
        (graph.QoS(), "::,:,:,:,,"),
        (graph.QoS(depth=10), "::,10:,:,:,,"),
        (graph.QoS(reliability=graph.BEST_EFFORT, depth=5), "2::,5:,:,:,,"),
        (graph.QoS(durability=graph.TRANSIENT_LOCAL, depth=1), ":1:,1:,:,:,,"),
        (graph.QoS(history=graph.KEEP_ALL, depth=1), "::2,1:,:,:,,"),
    ],
)
def test_qos_strings(qos, text):
    assert qos.keyexpr() == text
    assert graph.QoS.parse(text) == qos


def test_qos_parse_rejects_what_rmw_rejects():
    for bad in ("", "::,10", "x::,10:,:,:,,", "::10:,:,:,,"):
        with pytest.raises(ValueError):
            graph.QoS.parse(bad)


def test_node_and_endpoint_tokens():
    node = graph.Node(domain=0, zid=ZID, nid=3, namespace="/op1", name="darwin")
    assert node.token() == f"@ros2_lv/0/{ZID}/3/3/NN/%/%op1/darwin"
    tok = node.entity_token(
        5,
        graph.Kind.PUBLISHER,
        "/op1/joint_states",
        dds_type("sensor_msgs/msg/JointState"),
        type_hash("sensor_msgs/msg/JointState"),
        graph.QoS(depth=10),
    )
    assert tok == (
        f"@ros2_lv/0/{ZID}/3/5/MP/%/%op1/darwin/%op1%joint_states/"
        "sensor_msgs::msg::dds_::JointState_/RIHS01_"
        + HASHES["sensor_msgs/msg/JointState"]
        + "/::,10:,:,:,,"
    )
    e = graph.parse_token(tok)
    assert (e.kind, e.namespace, e.node, e.topic) == (
        graph.Kind.PUBLISHER,
        "/op1",
        "darwin",
        "/op1/joint_states",
    )
    assert e.qos == graph.QoS(depth=10)
    root = graph.Node(domain=2, zid=ZID, nid=0, namespace="/", name="talker")
    assert root.token() == f"@ros2_lv/2/{ZID}/0/0/NN/%/%/talker"
    assert graph.parse_token(root.token()).namespace == "/"


def test_service_token_uses_the_service_type():
    node = graph.Node(domain=0, zid=ZID, nid=0, namespace="/op1", name="darwin")
    tok = node.entity_token(
        9,
        graph.Kind.SERVICE,
        "/op1/halt",
        dds_type("std_srvs/srv/Trigger"),
        type_hash("std_srvs/srv/Trigger"),
        graph.SERVICE_QOS,
    )
    assert "/SS/%/%op1/darwin/%op1%halt/std_srvs::srv::dds_::Trigger_/RIHS01_eeff2cd6" in tok


def test_parse_token_rejects_garbage():
    for bad in ("@ros2_lv/0/z/0/0/XX/%/%/n", "foo/0/z/0/0/NN/%/%/n", "@ros2_lv/0/z/0/0/MP/%/%/n"):
        with pytest.raises(ValueError):
            graph.parse_token(bad)


def test_attachment_layout_and_gid():
    token = f"@ros2_lv/0/{ZID}/0/1/MP/%/%op1/darwin/%op1%imu%data/x/y/::,:,:,:,,"
    gid = gid_of(token)
    h = xxhash.xxh3_128_intdigest(token.encode())
    assert gid == struct.pack("<QQ", h & (2**64 - 1), h >> 64)  # low 64 bits first
    raw = Attachment(1, 1_700_000_000_123_456_789, gid).encode()
    assert len(raw) == SIZE == 33
    assert raw[:8] == (1).to_bytes(8, "little")
    assert raw[8:16] == (1_700_000_000_123_456_789).to_bytes(8, "little")
    assert raw[16] == 0x10
    assert raw[17:] == gid
    assert Attachment.decode(raw) == Attachment(1, 1_700_000_000_123_456_789, gid)


def test_sequence_numbers_start_at_one_per_publisher():
    a, b = Sequencer(b"a" * 16), Sequencer(b"b" * 16)
    assert [Attachment.decode(a.next(5)).sequence for _ in range(3)] == [1, 2, 3]
    assert Attachment.decode(b.next(5)).sequence == 1


@pytest.mark.parametrize("raw", [None, b"", bytes(32), bytes(34), bytes(16) + b"\x08" + bytes(16)])
def test_bad_attachments_are_named(raw):
    with pytest.raises(AttachmentError):
        Attachment.decode(raw)


def test_cdr_golden_and_roundtrip():
    assert encode(msg_class("std_msgs/msg/String")(data="hello"), "std_msgs/msg/String").hex() == (
        "000100000600000068656c6c6f00"
    )
    req = msg_class("std_srvs/srv/Trigger_Request")(structure_needs_at_least_one_member=0)
    assert encode(req, "std_srvs/srv/Trigger_Request") == b"\x00\x01\x00\x00\x00"
    Header = msg_class("std_msgs/msg/Header")
    Time = msg_class("builtin_interfaces/msg/Time")
    js = msg_class("sensor_msgs/msg/JointState")(
        header=Header(stamp=Time(sec=3, nanosec=4), frame_id=""),
        name=["j_pan", "j_tilt"],
        position=np.array([0.1, -0.2]),
        velocity=np.array([0.0, 0.0]),
        effort=np.array([0.5, 0.25]),
    )
    raw = encode(js, "sensor_msgs/msg/JointState")
    back = decode(raw, "sensor_msgs/msg/JointState")
    assert back.name == ["j_pan", "j_tilt"]
    np.testing.assert_array_equal(back.position, [0.1, -0.2])


@pytest.mark.parametrize(
    "raw", [b"", b"\x00\x01\x00\x00", b"\x07\x07\x00\x00abc", b"\x00\x01\x00\x00\xff\xff\xff\x7f"]
)
def test_malformed_cdr_is_a_named_error(raw):
    with pytest.raises(CdrError, match="geometry_msgs/msg/Twist"):
        decode(raw, "geometry_msgs/msg/Twist")
