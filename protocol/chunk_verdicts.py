"""The verdict on one COBS chunk, shared by the stdlib decoder (decoder.py) and the compiled one (fast_frames.py).

Kept apart from both so that neither imports the other: decoder.py loads fast_frames through compiled.py, and
fast_frames needs these numbers, so they live below both.
"""

from __future__ import annotations

CHUNK_OK, CHUNK_OVERSIZE, CHUNK_COBS_ERROR, CHUNK_RUNT, CHUNK_CRC_ERROR, CHUNK_INCOMPATIBLE = range(6)
# The DecoderStats counter each rejected verdict adds to (indexed by the verdict; CHUNK_OK counts nothing).
REJECTED_AS = ("", "oversize", "cobs_errors", "runts", "crc_errors", "incompatible")
