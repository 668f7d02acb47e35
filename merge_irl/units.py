"""Units shared by every layer: feet and metres, NGSIM's frame.

NGSIM (and so the trajectory and encounter tables) measure in feet, ft/s and ft/s^2 with
frames of 0.1 s; SUMO measures in metres. This module is a leaf: it imports nothing, so
``scenarios`` (which imports nothing else of ours) may import it too.
"""

#: Metres in one foot (exact, international foot).
M_PER_FT = 0.3048
#: Feet in one metre.
FT_PER_M = 1.0 / M_PER_FT
#: One NGSIM frame, seconds (``Frame_ID`` steps of 0.1 s; ``Global_Time`` in ms).
FRAME_S = 0.1
