"""The ROBOTIS action file and the project's text format: reading, writing, round trips."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

import pytest

from config.loader import load_robot
from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.binfile import MotionFileError, Page, Step
from robot_daemon.motion.action.library import LIBRARY_DIR, MotionLibrary, load_library
from tests.fixtures.emulator import darwin_command
from tests.shared_data import STOCK_MOTIONS as STOCK
from tests.shared_data import STOCK_MOTIONS_MD5 as STOCK_MD5

needs_stock = pytest.mark.skipif(not STOCK.exists(), reason="stock motion_4096.bin not present")
REPO = Path(__file__).resolve().parents[2]


@needs_stock
def test_stock_file_pages_names_steps_and_checksum_rule() -> None:
    data = STOCK.read_bytes()
    assert hashlib.md5(data).hexdigest() == STOCK_MD5
    pages = binfile.parse_bin(data)
    assert len(pages) == 256
    by = {p.number: p for p in pages}
    assert by[0].zero
    assert (by[1].name, len(by[1].steps)) == ("init", 2)
    assert (by[9].name, len(by[9].steps)) == ("walkready", 1)
    assert (by[15].name, len(by[15].steps)) == ("sit down", 1)
    assert (by[4].name, len(by[4].steps)) == ("hi", 4)
    assert by[24].next == 25 and by[41].next == 42
    assert by[4].steps[1].pause == 25 and by[4].steps[0].time == 50
    for n in range(1, 256):
        chunk = data[n * 512 : (n + 1) * 512]
        assert binfile.checksum_ok(chunk), n
        assert by[n].checksum is None  # valid pages need no stored checksum
    assert not binfile.checksum_ok(data[:512])  # page 0 is all zeros


@needs_stock
def test_stock_file_bin_text_bin_is_byte_identical(tmp_path: Path) -> None:
    pages = binfile.read_bin(STOCK)
    assert binfile.build_bin(pages) == STOCK.read_bytes()
    text = textfile.dumps(pages)
    assert binfile.build_bin(textfile.loads(text)) == STOCK.read_bytes()


@needs_stock
def test_cli_converts_stock_to_text_and_back(tmp_path: Path) -> None:
    txt, back = tmp_path / "stock.toml", tmp_path / "back.bin"
    cmd = darwin_command("motion", "convert")
    subprocess.run([*cmd, str(STOCK), str(txt)], check=True, cwd=REPO, capture_output=True)
    assert 'name = "sit down"' in txt.read_text()
    subprocess.run([*cmd, str(txt), str(back)], check=True, cwd=REPO, capture_output=True)
    assert back.read_bytes() == STOCK.read_bytes()
    again = subprocess.run([*cmd, str(txt), str(back)], cwd=REPO, capture_output=True, text=True)
    assert again.returncode == 1 and "--force" in again.stderr


def test_a_written_page_obeys_the_checksum_rule_and_reads_back() -> None:
    step = Step(time=100, pause=5)
    step.words[13] = 2600
    page = Page(7, name="test", steps=[step], next=8)
    raw = page.pack()
    assert len(raw) == 512 and binfile.checksum_ok(raw)
    back = Page.unpack(7, raw)
    assert (back.name, back.next, back.steps[0].words[13], back.steps[0].pause) == (
        "test",
        8,
        2600,
        5,
    )
    assert not back.steps[0].driven(14)


def test_a_corrupted_checksum_is_kept_not_fixed() -> None:
    raw = bytearray(Page(3, name="x", steps=[Step(time=1)]).pack())
    raw[binfile.OFF_CHECKSUM] ^= 0x5A
    page = Page.unpack(3, bytes(raw))
    assert page.checksum is not None
    assert page.pack() == bytes(raw)
    assert "checksum" in textfile.page_text(page, textfile.default_joint_names())


def test_bad_files_are_refused_with_a_clear_message(tmp_path: Path) -> None:
    with pytest.raises(MotionFileError, match="131072"):
        binfile.parse_bin(b"\0" * 100)
    with pytest.raises(MotionFileError, match="unknown joint 'r_tail'"):
        textfile.loads('[[page]]\nnumber = 3\nname = "x"\n[[page.step]]\ntime = 5\nr_tail = 3\n')
    with pytest.raises(MotionFileError, match="outside the servo's range"):
        textfile.loads("[[page]]\nnumber = 3\n[[page.step]]\ntime = 5\nr_knee = 400\n")
    with pytest.raises(MotionFileError, match="page 3 appears twice"):
        textfile.loads("[[page]]\nnumber = 3\n[[page]]\nnumber = 3\n")
    with pytest.raises(MotionFileError, match="not valid TOML"):
        textfile.loads("[[page]\n")
    # Text holds longer pages than the .bin: 8 steps read, but do not fit a .bin page.
    long = textfile.loads("[[page]]\nnumber = 3\n" + "[[page.step]]\ntime = 1\n" * 8)
    with pytest.raises(MotionFileError, match="at most 7") as err:
        binfile.build_bin(long)
    assert err.value.field == "step"
    with pytest.raises(MotionFileError, match="at most 32") as err:
        textfile.loads("[[page]]\nnumber = 3\n" + "[[page.step]]\ntime = 1\n" * 33)
    assert err.value.field == "step"


def test_project_library_has_the_stock_numbers_and_stays_within_limits() -> None:
    lib = load_library()
    robot = load_robot()
    assert lib.violations(robot) == []
    expected = {
        1: "stand",
        9: "walk ready",
        10: "get up front",
        11: "get up back",
        12: "right kick",
        13: "left kick",
        15: "sit down",
        16: "stand up",
        4: "hi",
        41: "introduction",
        24: "wow",
        23: "yes",
        54: "clap",
        27: "oops",
        38: "bye",
        3: "no",
        60: "bow",
    }
    for number, name in expected.items():
        assert lib.page(number).name == name
        assert lib.page(name).number == number
    assert lib.page("Sit_Down").number == 15
    assert lib.chain(41) == [41, 42]
    with pytest.raises(KeyError, match="no action page 200"):
        lib.page(200)
    # The text library converts to a .bin whose pages read back the same.
    pages = binfile.parse_bin(binfile.build_bin(list(lib.pages.values())))
    again = MotionLibrary(pages)
    assert again.pages.keys() == lib.pages.keys()
    assert all(again.pages[n].pack() == lib.pages[n].pack() for n in lib.pages)
    assert len(list(LIBRARY_DIR.glob("*.toml"))) == len(lib)
