"""``recover(path)``: rewrite a truncated or damaged recording as a complete, indexed MCAP.

What :class:`clients.recording.scan.RecordScanner` finds whole and sound (schemas, channels,
messages, metadata, attachments) goes through the ``mcap`` package's own ``Writer``, which adds
chunk and message indexes, statistics and the summary, so every MCAP tool opens the result. A
``darwin.recovery`` metadata record in the new file names the source, the cut and the losses.
"""

from __future__ import annotations

import contextlib
import os
from collections import Counter
from dataclasses import dataclass, field

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from clients.recording.scan import NotMcapError, RecordScanner, ScanReport
from schemas.errors import RecordingError

RECOVERED_SUFFIX = ".recovered.mcap"
CHUNK_BYTES = 1024 * 1024
LIBRARY = "darwin record recover"


class RecoverError(RecordingError):
    """Nothing could be recovered, or the output is not allowed; the message says which."""


def default_output(path: str) -> str:
    """``walk.mcap`` → ``walk.recovered.mcap`` (any other name gets the suffix appended)."""
    base, ext = os.path.splitext(path)
    return (base if ext.lower() == ".mcap" else path) + RECOVERED_SUFFIX


@dataclass
class Recovery:
    """What :func:`recover` kept of a damaged recording, and what it lost."""

    source: str
    output: str
    report: ScanReport
    counts: dict[str, int] = field(default_factory=dict)  # MCAP topic → messages kept
    metadata: int = 0
    attachments: int = 0
    schemaless: Counter[str] = field(default_factory=Counter)  # topic → lost with its schema
    written: bool = False

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def dropped(self) -> list[str]:
        out = self.report.drops()
        lost = self.schemaless.items()
        out += [f"{n} messages of {topic}, whose schema was lost" for topic, n in lost]
        return out

    def lines(self) -> list[str]:
        """The report ``darwin record recover`` prints."""
        rep = self.report
        out = [f"{self.source} {rep.where()}"]
        if not self.written:
            return [*out, f"{self.source}: nothing to recover"]
        extra = f", {self.metadata} metadata" + (
            f", {self.attachments} attachments" if self.attachments else ""
        )
        out.append(f"{self.output}: kept {self.total} messages{extra}")
        out += [f"  {topic}: {n}" for topic, n in sorted(self.counts.items())]
        drops = self.dropped()
        out.append("dropped: " + ("; ".join(drops) if drops else "nothing"))
        return out


def recovered_copy(path: str) -> str | None:
    """The default recovered file of ``path`` when it was made from ``path`` as it is now."""
    copy = default_output(path)
    try:
        with open(copy, "rb") as f:
            meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
        info = meta.get("darwin.recovery", {})
        same = info.get("source") == os.path.basename(path)
        return copy if same and info.get("source_bytes") == str(os.path.getsize(path)) else None
    except (OSError, McapError, ValueError, EOFError):
        return None


def _check_output(source: str, output: str, overwrite: bool) -> None:
    if os.path.exists(output):
        same = os.path.samefile(source, output)
        if same and not overwrite:
            raise RecoverError(
                f"{output} is the file being recovered; pass --in-place to replace it"
            )
        if not same and not overwrite:
            raise RecoverError(f"{output} exists; pass --force to overwrite it or -o another name")
    folder = os.path.dirname(os.path.abspath(output))
    if not os.path.isdir(folder):
        raise RecoverError(f"cannot write {output}: no folder {folder}")


def recover(
    path: str | os.PathLike[str],
    output: str | os.PathLike[str] | None = None,
    *,
    overwrite: bool = False,
    always: bool = False,
    chunk_bytes: int = CHUNK_BYTES,
) -> Recovery:
    """Rewrite ``path`` into ``output`` (default: :func:`default_output`).

    A file that is complete and sound is left alone (``written`` False) unless ``always``.
    Raises :class:`RecoverError` when the input holds no MCAP data or the output is refused.
    """
    source = os.fspath(path)
    target = os.fspath(output) if output is not None else default_output(source)
    if not os.path.isfile(source):
        raise RecoverError(f"cannot read {source}: no such file")
    _check_output(source, target, overwrite)
    scanner = RecordScanner(source)
    result = Recovery(source, target, scanner.report)
    part = f"{target}.part"
    try:
        with open(part, "wb") as f:
            writer = Writer(f, chunk_size=chunk_bytes, compression=CompressionType.ZSTD)
            _copy(scanner, writer, result)
            rep = scanner.report
            writer.add_metadata(
                "darwin.recovery",
                {
                    "source": os.path.basename(source),
                    "source_bytes": str(rep.size),
                    "readable_bytes": str(rep.size if rep.cut_at is None else rep.cut_at),
                    "where": rep.where(),
                    "dropped": "; ".join(result.dropped()) or "nothing",
                },
            )
            writer.finish()
            f.flush()
            os.fsync(f.fileno())
        if scanner.report.damaged or always:
            os.replace(part, target)
            result.written = True
    except NotMcapError as exc:
        raise RecoverError(f"{exc}: nothing to recover") from exc
    except OSError as exc:
        raise RecoverError(f"cannot recover {source} into {target}: {exc}") from exc
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.remove(part)
    return result


def _copy(scanner: RecordScanner, writer: Writer, result: Recovery) -> None:
    schemas: dict[int, int] = {}
    channels: dict[int, int] = {}
    topics: dict[int, str] = {}
    lost: dict[int, str] = {}  # channel id → topic, for channels whose schema was lost
    for record in scanner:
        if isinstance(record, Message):
            cid = channels.get(record.channel_id)
            if cid is None:
                result.schemaless[lost.get(record.channel_id, "?")] += 1
                continue
            writer.add_message(
                cid, record.log_time, record.data, record.publish_time, record.sequence
            )
            topic = topics[record.channel_id]
            result.counts[topic] = result.counts.get(topic, 0) + 1
        elif isinstance(record, Channel):
            if record.id in channels or record.id in lost:
                continue
            if record.schema_id and record.schema_id not in schemas:
                lost[record.id] = record.topic
                continue
            channels[record.id] = writer.register_channel(
                record.topic,
                record.message_encoding,
                schemas.get(record.schema_id, 0),
                dict(record.metadata),
            )
            topics[record.id] = record.topic
        elif isinstance(record, Schema):
            if record.id not in schemas:
                schemas[record.id] = writer.register_schema(
                    record.name, record.encoding, record.data
                )
        elif isinstance(record, Metadata):
            writer.add_metadata(record.name, dict(record.metadata))
            result.metadata += 1
        elif isinstance(record, Attachment):
            writer.add_attachment(
                record.create_time, record.log_time, record.name, record.media_type, record.data
            )
            result.attachments += 1
        elif isinstance(record, Header):
            library = f"{record.library}; {LIBRARY}" if record.library else LIBRARY
            writer.start(profile=record.profile, library=library)
