# Copyright 2026 gyro_platform developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""Where a rosbag2 bag's files are: path checks (ROS 1 bags, stray files), its storage files,
``metadata.yaml`` and storage kind (``sqlite3``/``mcap``); the lazily imported rosbags pieces.

Shared by :mod:`.bag_reader` (the intact bag) and :mod:`.bag_salvage` (the damaged bag).
"""
from __future__ import annotations

from pathlib import Path

from ..errors import BagPathError

ROS1_MAGIC = b"#ROSBAG V2.0"


def rosbags_api():
    """The rosbags pieces used by the bag modules, imported on first use (keeps ``--help`` fast)."""
    from rosbags.interfaces import Connection, ConnectionExtRosbag2, MessageDefinition, MessageDefinitionFormat
    from rosbags.rosbag2 import Reader, ReaderError
    from rosbags.typesys import get_types_from_idl, get_types_from_msg, get_typestore, Stores

    return {"Connection": Connection, "Ext": ConnectionExtRosbag2, "MsgDef": MessageDefinition,
            "MsgDefFormat": MessageDefinitionFormat, "Reader": Reader, "ReaderError": ReaderError,
            "Stores": Stores, "from_idl": get_types_from_idl, "from_msg": get_types_from_msg,
            "get_typestore": get_typestore}


def storage_files(path: Path) -> list[Path]:
    """Storage files of a bag directory (metadata order if readable) or the file itself."""
    if path.is_file():
        return [path]
    meta = read_metadata(path)
    if meta and meta.get("relative_file_paths"):
        files = [path / Path(p).name for p in meta["relative_file_paths"]]
        return [f for f in files if f.exists()]
    return sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))


def resolve_bag_path(path: Path) -> Path:
    """The bag to open for a user's path: a bag's ``metadata.yaml`` stands for its folder.
    BagPathError for a missing path, a ROS 1 bag and folders or files that hold no bag."""
    if not path.exists():
        raise BagPathError(f"{path}: no such file or directory")
    if not (path.is_file() or path.is_dir()):          # a FIFO, a socket, a device
        raise BagPathError(f"{path}: not a rosbag2 bag (neither a folder nor a regular file)")
    if path.is_file() and path.name == "metadata.yaml":
        path = path.parent
    ros1 = [path] if path.is_file() else sorted(path.glob("*.bag"))
    for f in ros1:
        try:
            with f.open("rb") as fh:
                is_ros1 = fh.read(len(ROS1_MAGIC)) == ROS1_MAGIC
        except OSError as e:
            raise BagPathError(f"{f}: cannot read: {e.strerror or e}") from None
        if is_ros1 or (f.suffix == ".bag" and path.is_file()):
            raise BagPathError(f"{f}: a ROS 1 bag; convert it to rosbag2 first "
                               f"(rosbags-convert --src {f} --dst OUT_DIR)")
    if path.is_file() and path.suffix not in (".db3", ".mcap"):
        raise BagPathError(f"{path}: not a rosbag2 bag (give a bag folder with metadata.yaml, "
                           f"or a .db3 / .mcap file)")
    return path


def reader_path(path: Path) -> Path:
    """What rosbags' Reader opens: the folder when it has ``metadata.yaml``, else its single
    storage file (rosbags reads a lone .db3/.mcap file without metadata). A folder of several
    storage files without metadata cannot be ordered: BagPathError naming the fix."""
    if path.is_file() or (path / "metadata.yaml").is_file():
        return path
    files = storage_files(path)
    if len(files) == 1:
        return files[0]
    if not files:
        raise BagPathError(f"{path}: not a rosbag2 bag (no metadata.yaml, no .db3 / .mcap file)")
    raise BagPathError(f"{path}: {len(files)} storage files but no metadata.yaml; "
                       f"recreate it with 'ros2 bag reindex {path}'")


def read_metadata(path: Path) -> dict | None:
    """``rosbag2_bagfile_information`` of ``path/metadata.yaml``, None if absent or unreadable
    (YAML safe loading, by libyaml where present; the last file read is remembered: do not
    change the dict)."""
    try:
        import yaml

        text = (path / "metadata.yaml").read_text()
        if _LAST_METADATA[0] != (path, text):
            loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
            _LAST_METADATA[:] = [(path, text), yaml.load(text, Loader=loader)]
        doc = _LAST_METADATA[1]
        return doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    except Exception:
        return None


_LAST_METADATA: list = [None, None]     # ((path, text), document) of the last read_metadata


def storage_of(path: Path) -> str:
    """``sqlite3`` or ``mcap`` for a bag directory or storage file."""
    files = storage_files(path) if path.is_dir() else [path]
    meta = read_metadata(path) if path.is_dir() else None
    if meta and meta.get("storage_identifier") in ("sqlite3", "mcap"):
        return meta["storage_identifier"]
    for f in files:
        if f.suffix == ".mcap":
            return "mcap"
        if f.suffix == ".db3":
            return "sqlite3"
    raise BagPathError(f"{path}: not a rosbag2 bag (give a bag folder with metadata.yaml, "
                       f"or a .db3 / .mcap file)")
