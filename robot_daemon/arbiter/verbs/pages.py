"""The ``pages`` verb: the action-page library, read and written (teach mode, action editor).

| op | fields | lease | reply |
|---|---|---|---|
| list | — | no | pages: [{number, name, steps, repeat, speed, next, exit, origin}], user_library |
| get | number | no | page: the page table (as a TOML page file holds it), origin |
| put | page: the page table | yes | number, name, steps, path (the user file written) |
| delete | number | yes | number, restored (a shipped page of that number is back) |
| reload | — | yes | pages, read (files parsed again), problems |
| export | — | no | bin: the ROBOTIS ``.bin`` bytes (131 072), pages |
| play | number, step (1-based, default 1) | yes | number, name, step |

Pages are saved in the user's motion library, never in the installed package
(:mod:`robot_daemon.motion.action.store`). Every page put or played is checked against the
configured joint limits and the format's rules; a refusal names the field (``page.name``,
``page.step[2].r_elbow``, ``page.next``…).
"""

from __future__ import annotations

from typing import Any

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.binfile import MotionFileError, Page
from robot_daemon.motion.action.check import bin_problems, page_problems
from robot_daemon.motion.action.player import ActionModule
from robot_daemon.motion.action.store import PageStore
from schemas.errors import ErrorCode


def _parts(ctx: MotionContext) -> tuple[ActionModule, PageStore]:
    player = ctx.manager.get("action")
    if not isinstance(player, ActionModule) or player.store is None:
        raise Reject(ErrorCode.UNAVAILABLE, "this daemon has no action page library to edit")
    return player, player.store


def _number(req: Request, player: ActionModule) -> int:
    number = F.integer(req.fields, "number", 1, 255)
    if number not in player.library:
        raise Reject(
            ErrorCode.UNKNOWN,
            f"no action page {number}; pages are "
            f"{', '.join(map(str, sorted(player.library.pages)))}",
            "number",
        )
    return number


def _summary(store: PageStore, number: int) -> dict[str, Any]:
    return page_summary(number, store.library.pages[number], store.origin(number))


def page_summary(number: int, p: Page, origin: str) -> dict[str, Any]:
    """One row of the ``pages`` listing."""
    return {
        "number": number,
        "name": p.name,
        "steps": len(p.steps),
        "repeat": p.repeat,
        "speed": p.speed,
        "next": p.next,
        "exit": p.exit,
        "origin": origin,
    }


def _use(player: ActionModule, store: PageStore) -> None:
    # The player keeps the Page it is playing; only later look-ups see the new library.
    player.library = store.library


@verb("pages")
def pages(req: Request, ctx: MotionContext) -> dict[str, Any]:
    player, store = _parts(ctx)
    op = req.op.name
    if op == "list":
        return {
            "op": op,
            "pages": [_summary(store, n) for n in sorted(store.library.pages)],
            "user_library": str(store.user_dir),
            "problems": list(store.problems),
        }
    if op == "get":
        number = _number(req, player)
        page = textfile.page_to_dict(store.library.pages[number], store.names)
        return {"op": op, "page": page, "origin": store.origin(number)}
    if op == "put":
        return _put(req, ctx, player, store)
    if op == "delete":
        return _delete(req, player, store)
    if op == "reload":
        try:
            result = store.reload()
        except (MotionFileError, OSError) as exc:
            raise Reject(ErrorCode.UNAVAILABLE, f"cannot read the shipped library: {exc}") from None
        _use(player, store)
        return {"op": op, **result}
    if op == "export":
        bad = bin_problems(store.library.pages.values())
        if bad:
            raise Reject(ErrorCode.INVALID, f"cannot export to .bin: {bad[0]}", bad[0].field)
        try:
            data = binfile.build_bin(store.library.pages)
        except MotionFileError as exc:
            raise Reject(ErrorCode.INVALID, f"cannot export to .bin: {exc}", exc.field) from None
        return {"op": op, "bin": data, "pages": sorted(store.library.pages)}
    number = _number(req, player)
    step = F.integer(req.fields, "step", 1, 255, default=1)
    try:
        played = player.play(number, step)
    except KeyError as exc:
        raise Reject(ErrorCode.UNKNOWN, str(exc.args[0]), "step") from None
    except ValueError as exc:
        raise Reject(ErrorCode.OUT_OF_RANGE, str(exc), "number") from None
    return {"op": op, "number": played.number, "name": played.name, "step": step}


def _put(
    req: Request, ctx: MotionContext, player: ActionModule, store: PageStore
) -> dict[str, Any]:
    table = F.present(req.fields, "page")
    if not isinstance(table, dict):
        raise Reject(ErrorCode.INVALID, f"page must be a page table, got {table!r}", "page")
    try:
        page = textfile.page_from_dict(table, store.names, "pages put")
    except MotionFileError as exc:
        raise Reject(ErrorCode.INVALID, str(exc), f"page.{exc.field or ''}".rstrip(".")) from None
    if page.zero:
        raise Reject(ErrorCode.INVALID, "a saved page needs steps, not zero = true", "page.zero")
    known = set(store.library.pages) | {page.number}
    bad = page_problems(page, ctx.robot, known)
    if bad:
        limits = "°" in bad[0].message
        code = ErrorCode.OUT_OF_RANGE if limits else ErrorCode.INVALID
        raise Reject(code, bad[0].message, f"page.{bad[0].field}")
    try:
        path = store.put(page)
    except (OSError, MotionFileError) as exc:
        raise Reject(
            ErrorCode.UNAVAILABLE,
            f"cannot save page {page.number} in {store.user_dir}: {exc} "
            "(check [motion] user_library / $DARWIN_MOTIONS)",
            "page",
        ) from None
    _use(player, store)
    return {"op": "put", **_summary(store, page.number), "path": str(path)}


def _delete(req: Request, player: ActionModule, store: PageStore) -> dict[str, Any]:
    number = F.integer(req.fields, "number", 1, 255)
    if number not in store.user:
        if number in store.shipped:
            raise Reject(
                ErrorCode.REFUSED,
                f"page {number} is a shipped page: it cannot be deleted (put a page with its "
                "number to replace it)",
                "number",
            )
        raise Reject(ErrorCode.UNKNOWN, f"no page {number} in the user library", "number")
    if number in player.in_use():
        raise Reject(
            ErrorCode.REFUSED,
            f"page {number} is being played (or chained from the page playing): stop it first "
            "(`action` op=stop)",
            "number",
        )
    if number not in store.shipped:
        for other, p in sorted(store.library.pages.items()):
            key = "next" if p.next == number else "exit" if p.exit == number else None
            if key and other != number:
                raise Reject(
                    ErrorCode.REFUSED,
                    f"page {other} ({p.name}) leads to page {number} ({key}): change it first",
                    "number",
                )
    try:
        result = store.delete(number)
    except OSError as exc:
        message = f"cannot delete page {number}: {exc}"
        raise Reject(ErrorCode.UNAVAILABLE, message, "number") from None
    _use(player, store)
    return {"op": "delete", "number": number, **result}
