"""MCAP files: the only package importing `mcap` (writer: crash-safe recording; reader: tolerant, bounded reads)."""

from groundstation.mcap_io.reader import (
    DECODED_FLOOR_BYTES,
    DECODED_PER_DISK_BYTE,
    RecordedMessage,
    RecordingContents,
    is_complete,
    iter_messages,
    iter_topic_data,
    read_header,
    read_recording,
    recover,
)
from groundstation.mcap_io.writer import (
    JSON,
    JSONSCHEMA,
    MAGIC,
    PROFILE,
    RAW_ENCODING,
    McapFileWriter,
    mcap_library_version,
)

__all__ = [
    "DECODED_FLOOR_BYTES", "DECODED_PER_DISK_BYTE", "JSON", "JSONSCHEMA", "MAGIC", "PROFILE", "RAW_ENCODING",
    "McapFileWriter", "RecordedMessage", "RecordingContents", "is_complete", "iter_messages", "iter_topic_data",
    "mcap_library_version", "read_header", "read_recording", "recover",
]
