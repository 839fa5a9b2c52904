"""The output rosbag2 bag (version 9, sqlite3 or mcap): input connections copied byte for
byte plus the simulator's output topics, offered with the rclpy default QoS."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from . import messages as msgs
from .bag_paths import rosbags_api


def default_qos() -> list:
    """QoS offered by the output publishers: reliable, volatile, keep last 10 (rclpy default)."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                    QosTime)

    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]


class OutputBag:
    """rosbag2 version-9 writer that copies input connections and adds the output topics."""

    def __init__(self, path: Path, storage: str):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = path
        self.storage = storage
        plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
        self.writer = Writer(path, version=9, storage_plugin=plugin)
        self.writer.open()
        self._copies: dict[int, Any] = {}     # input connection id -> output connection
        self._by_key: dict[tuple, Any] = {}
        self._outs: dict[str, Any] = {}
        self.skipped: dict[str, str] = {}     # input topics that could not be copied -> why
        self.counts: dict[str, int] = {}
        self.closed = False

    def copy_connection(self, conn: Any, store: Any) -> Any | None:
        """Output connection for an input connection (same topic, type, definition, QoS)."""
        if conn.id in self._copies:
            return self._copies[conn.id]
        key = (conn.topic, conn.msgtype, conn.ext.serialization_format, tuple(conn.ext.offered_qos_profiles))
        out = self._by_key.get(key)
        if out is None:
            out = self._add_copy(conn, store)
            if out is not None:
                self._by_key[key] = out
        self._copies[conn.id] = out
        return out

    def _add_copy(self, conn: Any, store: Any) -> Any | None:
        rb = rosbags_api()
        msgdef, digest = None, None
        if conn.msgdef.format != rb["MsgDefFormat"].NONE and conn.msgdef.data:
            msgdef = conn.msgdef.data
            digest = conn.digest or None
            if digest is None:
                try:
                    digest = store.hash_rihs01(conn.msgtype)
                except Exception:
                    digest = None
        if msgdef is None or digest is None:
            jazzy = msgs.jazzy_typestore()
            if conn.msgtype not in jazzy.fielddefs:
                self.skipped[conn.topic] = f"type {conn.msgtype} has no definition in the bag nor in Jazzy"
                return None
            msgdef, _ = jazzy.generate_msgdef(conn.msgtype, ros_version=2)
            digest = jazzy.hash_rihs01(conn.msgtype)
        return self.writer.add_connection(conn.topic, conn.msgtype, msgdef=msgdef, rihs01=digest,
                                          serialization_format=conn.ext.serialization_format,
                                          offered_qos_profiles=conn.ext.offered_qos_profiles)

    def add_output(self, topic: str, msgtype: str) -> None:
        """Add an output topic; an input topic of the same name and type is shared (/diagnostics)."""
        shared = next((c for c in self._copies.values() if c is not None and c.topic == topic
                       and c.msgtype == msgtype), None)
        self._outs[topic] = shared or self.writer.add_connection(
            topic, msgtype, typestore=msgs.jazzy_typestore(), offered_qos_profiles=default_qos())

    def write_raw(self, out_conn: Any, ts: int, raw: bytes) -> None:
        """Write CDR bytes on an output connection at record time ``ts`` (ns)."""
        self.writer.write(out_conn, ts, raw)
        self.counts[out_conn.topic] = self.counts.get(out_conn.topic, 0) + 1

    def write_msg(self, topic: str, ts: int, msg: Any) -> None:
        """Serialise a Jazzy message and write it on output topic ``topic`` at ``ts`` (ns)."""
        raw = msgs.jazzy_typestore().serialize_cdr(msg, msg.__msgtype__)
        self.write_raw(self._outs[topic], ts, raw)

    def close(self) -> None:
        """Write index and metadata (the bag is then readable); falls back to abort on failure."""
        if self.closed:
            return
        self.closed = True
        try:
            self.writer.close()
        except Exception:
            self.writer.abort()
            raise

