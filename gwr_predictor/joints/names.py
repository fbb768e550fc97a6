"""How many joint names an input may carry, and how long each: checked where a message or a tracker's
joint state is unpacked, before anything is sized by it (`pipeline.conventions`, `data.hri_bodies`).
"""

from __future__ import annotations

#: Joint names in one skeleton, prediction or joint state (a full-body tracker sends about 30).
MAX_JOINTS = 256
#: Characters in one joint name.
MAX_NAME_CHARS = 128
