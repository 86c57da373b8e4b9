"""The ``pages`` verb and the user's page library, on a real motion manager (no daemon): round
trips, persistence, refusals naming the field, a playing page kept, the .bin export."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from clients.pages import PageEditor
from config.loader import load_all
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, needs_lease
from robot_daemon.arbiter.verbs import pages as pages_verb
from robot_daemon.frames import JointFrame
from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.library import LIBRARY_DIR
from robot_daemon.motion.action.store import PageStore
from schemas.errors import ErrorCode
from tests.fixtures.emulator import darwin_command
from tests.fixtures.motion import motion_context
from tests.shared_data import STOCK_MOTIONS as STOCK

REPO = Path(__file__).resolve().parents[2]
needs_stock = pytest.mark.skipif(not STOCK.exists(), reason="stock motion_4096.bin not present")


def make_ctx(user_dir: Path) -> MotionContext:
    settings = load_all()
    settings["motion"]["user_library"] = str(user_dir)
    return motion_context(settings)


@pytest.fixture
def ctx(tmp_path: Path) -> MotionContext:
    return make_ctx(tmp_path / "motions")


def call(ctx: MotionContext, **fields) -> dict:
    return pages_verb.pages(Request("pages", "c1", "tester", fields), ctx)


def refused(ctx: MotionContext, **fields) -> Reject:
    with pytest.raises(Reject) as exc:
        call(ctx, **fields)
    return exc.value


def wave(number: int = 200, name: str = "wave") -> dict:
    return {
        "number": number,
        "name": name,
        "step": [
            {"time": 50, "pause": 0, "r_shoulder_pitch": -40.0, "r_elbow": 30.0},
            {"time": 40, "pause": 10, "r_shoulder_pitch": -120.0, "r_elbow": 60.0},
        ],
    }


def test_reads_are_free_and_writes_need_the_lease() -> None:
    for op in ("list", "get", "export"):
        assert not needs_lease("pages", {"op": op})
    for op in ("put", "delete", "reload", "play"):
        assert needs_lease("pages", {"op": op})


def test_put_get_delete_round_trip_persists_and_the_player_uses_it(
    ctx: MotionContext, tmp_path: Path
) -> None:
    put = call(ctx, op="put", page=wave())
    path = Path(put["path"])
    assert path.parent == tmp_path / "motions" and path.name == "200_wave.toml"
    assert (put["number"], put["steps"], put["origin"]) == (200, 2, "user")
    got = call(ctx, op="get", number=200)["page"]
    expected = {"time": 40, "pause": 10, "r_shoulder_pitch": -119.97, "r_elbow": 60.03}
    assert got["step"][1] == expected
    assert 200 in ctx.manager.module("action").library
    listed = {p["number"]: p for p in call(ctx, op="list")["pages"]}
    assert listed[200]["name"] == "wave" and listed[1]["origin"] == "shipped"
    # A new daemon (restart) finds it; the installed library was not touched.
    again = make_ctx(tmp_path / "motions")
    assert call(again, op="get", number=200)["page"] == got
    assert not list(LIBRARY_DIR.glob("200_*"))
    # Renaming moves the file; deleting removes it.
    call(ctx, op="put", page={**wave(), "name": "big wave"})
    assert sorted(p.name for p in path.parent.glob("*.toml")) == ["200_big_wave.toml"]
    assert call(ctx, op="delete", number=200)["restored"] is False
    assert not list(path.parent.glob("*.toml"))
    assert refused(ctx, op="get", number=200).code == ErrorCode.UNKNOWN


def test_a_user_page_replaces_a_shipped_one_until_deleted(ctx: MotionContext) -> None:
    shipped = call(ctx, op="get", number=4)["page"]
    call(ctx, op="put", page={**wave(4, "my hi")})
    assert call(ctx, op="get", number=4)["origin"] == "user (replaces shipped)"
    assert call(ctx, op="delete", number=4)["restored"] is True
    assert call(ctx, op="get", number=4)["page"] == shipped
    err = refused(ctx, op="delete", number=4)
    assert (err.code, err.field) == (ErrorCode.REFUSED, "number")


@pytest.mark.parametrize(
    ("change", "field", "code"),
    [
        (lambda p: p["step"][0].update(r_elbow=120.0), "page.step[0].r_elbow", "out_of_range"),
        (lambda p: p.update(name="a name too long"), "page.name", "invalid"),
        (lambda p: p.update(name="ação ☺"), "page.name", "invalid"),
        (lambda p: p.update(next=201), "page.next", "invalid"),
        (lambda p: p.update(exit=99), "page.exit", "invalid"),
        (lambda p: p["step"][1].update(time=0), "page.step[1].time", "invalid"),
        (lambda p: p["step"][1].update(time=300), "page.step[1].time", "invalid"),
        (lambda p: p["step"][0].update(r_tail=3), "page.step[0].r_tail", "invalid"),
        (lambda p: p["step"][0].update(r_knee="up"), "page.step[0].r_knee", "invalid"),
        (lambda p: p.update(colour="red"), "page.colour", "invalid"),
        (lambda p: p.update(step=[]), "page.step", "invalid"),
        (lambda p: p.update(step={"time": 3}), "page.step", "invalid"),
        (lambda p: p.update(step=[{"time": 5}] * 33), "page.step", "invalid"),
        (lambda p: p.update(number=0), "page.number", "invalid"),
        (lambda p: p.update(speed=0), "page.speed", "invalid"),
    ],
)
def test_invalid_pages_are_refused_naming_the_field(
    ctx: MotionContext, tmp_path: Path, change, field: str, code: str
) -> None:
    page = wave()
    change(page)
    err = refused(ctx, op="put", page=page)
    assert (err.field, err.code) == (field, code), err.message
    assert not (tmp_path / "motions").exists() or not list((tmp_path / "motions").glob("*"))
    assert 200 not in ctx.manager.module("action").library


def test_unknown_fields_and_wrong_types_are_named(ctx: MotionContext) -> None:
    assert refused(ctx, op="get", number=4, page=3).field == "page"
    assert refused(ctx, op="list", verbose=True).field == "verbose"
    assert refused(ctx, op="dance").field == "op"
    assert refused(ctx).field == "op"
    assert refused(ctx, op="get", number="4").field == "number"
    assert refused(ctx, op="put", page=[1, 2]).field == "page"
    assert refused(ctx, op="put").field == "page"
    assert refused(ctx, op="play", number=4, step=99).field == "step"


def test_next_may_name_a_page_saved_before_or_itself(ctx: MotionContext) -> None:
    call(ctx, op="put", page={**wave(), "next": 200})
    call(ctx, op="put", page={**wave(201, "then"), "next": 200, "exit": 1})
    err = refused(ctx, op="delete", number=200)
    assert err.code == ErrorCode.REFUSED and "page 201" in err.message


def tick(ctx: MotionContext, n: int = 1) -> None:
    robot = ctx.robot
    for t in range(n):
        frame = JointFrame(t, t * 0.008, 0.008, position=np.zeros(21))
        frame.online[:] = True
        frame.torque_enabled[:] = True
        ctx.manager.step(frame)
    assert robot


def test_a_page_being_played_cannot_be_deleted(ctx: MotionContext) -> None:
    call(ctx, op="put", page=wave())
    call(ctx, op="put", page=wave(202, "follow"))
    call(ctx, op="put", page={**wave(201, "lead"), "next": 202})
    played = call(ctx, op="play", number=200, step=2)
    assert (played["number"], played["step"]) == (200, 2)
    err = refused(ctx, op="delete", number=200)
    assert (err.code, err.field) == (ErrorCode.REFUSED, "number")
    tick(ctx, 3)
    assert ctx.manager.module("action").status()["step"] == 2
    assert refused(ctx, op="delete", number=200).code == ErrorCode.REFUSED
    # A page chained from the one playing is kept too.
    ctx.manager.halt()
    call(ctx, op="play", number=201)
    tick(ctx)
    assert refused(ctx, op="delete", number=202).code == ErrorCode.REFUSED
    ctx.manager.halt()
    call(ctx, op="put", page=wave(201, "lead"))  # no next any more
    assert call(ctx, op="delete", number=202)["number"] == 202
    assert call(ctx, op="delete", number=200)["number"] == 200


def test_play_checks_the_page_and_its_chain(tmp_path: Path) -> None:
    user = tmp_path / "motions"
    user.mkdir()
    bad = copy.deepcopy(wave(210, "bad"))
    bad["step"][0]["r_elbow"] = 120.0  # written by hand: beyond the limits
    (user / "210_bad.toml").write_text(textfile.dumps([textfile.page_from_dict(bad)]))
    ctx = make_ctx(user)
    err = refused(ctx, op="play", number=210)
    assert err.code == ErrorCode.OUT_OF_RANGE and "r_elbow" in err.message
    assert not ctx.manager.module("action").playing


def test_reload_reads_only_changed_files_and_skips_broken_ones(
    ctx: MotionContext, tmp_path: Path
) -> None:
    call(ctx, op="put", page=wave())
    assert call(ctx, op="reload")["read"] == 0  # nothing changed on disk
    user = tmp_path / "motions"
    (user / "201_hand.toml").write_text(textfile.dumps([textfile.page_from_dict(wave(201, "h"))]))
    (user / "202_broken.toml").write_text("[[page]]\nnumber = 202\nname = 3\n")
    result = call(ctx, op="reload")
    assert result["read"] == 2 and len(result["problems"]) == 1
    assert "202_broken.toml" in result["problems"][0]
    assert 201 in ctx.manager.module("action").library
    assert 202 not in ctx.manager.module("action").library
    assert call(ctx, op="list")["problems"] == result["problems"]


def test_export_round_trips_through_the_converter(ctx: MotionContext, tmp_path: Path) -> None:
    call(ctx, op="put", page=wave())
    data = call(ctx, op="export")["bin"]
    assert len(data) == binfile.FILE_SIZE
    out = tmp_path / "mine.bin"
    out.write_bytes(data)
    back = {p.number: p for p in binfile.read_bin(out) if not p.zero and not p.blank}
    store: PageStore = ctx.manager.module("action").store
    assert set(back) == set(store.library.pages)
    names = store.names
    for n, page in store.library.pages.items():
        assert textfile.page_text(back[n], names) == textfile.page_text(page, names)
    # …and the converter's text of it is the library's text.
    ours = store.library.pages.values()
    assert textfile.dumps(back.values(), names) == textfile.dumps(ours, names)


def test_export_refuses_what_a_bin_cannot_hold(ctx: MotionContext) -> None:
    long = wave()
    long["step"] = [dict(long["step"][i % 2]) for i in range(8)]
    call(ctx, op="put", page=long)  # the text library holds it…
    err = refused(ctx, op="export")  # …a ROBOTIS .bin does not
    assert err.field == "step" and "page 200" in err.message and "at most 7" in err.message


@needs_stock
def test_stock_file_loads_edits_and_saves_without_losing_data() -> None:
    data = STOCK.read_bytes()
    names = textfile.default_joint_names()
    pages = binfile.parse_bin(data)
    by = {p.number: p for p in pages}
    # Unchanged through the editor's table: byte-identical.
    tables = {
        p.number: textfile.page_to_dict(p, names) for p in pages if not p.zero and not p.blank
    }
    rebuilt = {n: textfile.page_from_dict(t, names) for n, t in tables.items()}
    assert binfile.build_bin({**by, **rebuilt}) == data
    # One value edited: only that page's position word and checksum byte change.
    editor = PageEditor(tables[15])
    editor.nudge(0, "head_tilt", 10.0)
    edited = textfile.page_from_dict(editor.page, names)
    out = binfile.build_bin({**by, 15: edited})
    diff = [i for i in range(len(data)) if data[i] != out[i]]
    word = 15 * 512 + 64 + 20 * 2  # page 15, step 1, slot 20 (head tilt)
    assert set(diff) <= {word, word + 1, 15 * 512 + binfile.OFF_CHECKSUM}
    assert binfile.checksum_ok(out[15 * 512 : 16 * 512])
    assert binfile.parse_bin(out)[15].steps[0].words[20] == by[15].steps[0].words[20] + 114


def test_cli_exports_the_library_with_the_user_pages(ctx: MotionContext, tmp_path: Path) -> None:
    import subprocess

    call(ctx, op="put", page=wave())
    out = tmp_path / "all.bin"
    cmd = darwin_command("motion", "export", str(out))
    user = ["--user-library", str(tmp_path / "motions")]
    done = subprocess.run([*cmd, *user], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == call(ctx, op="export")["bin"]
    # Back through the converter: the same text as the library's.
    txt = tmp_path / "all.toml"
    conv = darwin_command("motion", "convert", str(out), str(txt))
    subprocess.run(conv, check=True, capture_output=True, cwd=REPO)
    store: PageStore = ctx.manager.module("action").store
    assert txt.read_text() == textfile.dumps(store.library.pages.values(), store.names)
    long = wave()
    long["step"] = [dict(long["step"][0]) for _ in range(8)]
    call(ctx, op="put", page=long)
    refused_run = subprocess.run([*cmd, *user, "--force"], capture_output=True, text=True, cwd=REPO)
    assert refused_run.returncode == 1
    assert refused_run.stderr.count("\n") == 1 and "at most 7" in refused_run.stderr


def test_an_unwritable_user_library_is_refused_with_the_fix(tmp_path: Path) -> None:
    blocker = tmp_path / "motions"
    blocker.write_text("a file where the folder should be")
    ctx = make_ctx(blocker)
    err = refused(ctx, op="put", page=wave())
    assert (err.code, err.field) == (ErrorCode.UNAVAILABLE, "page")
    assert "user_library" in err.message and "DARWIN_MOTIONS" in err.message
    assert 200 not in ctx.manager.module("action").library
