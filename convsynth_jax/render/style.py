"""Colours and sizes of the drawings (a body keeps its colour all the time; sizes are fractions of a body's stature)."""
from __future__ import annotations




BODY_RGB = ((52, 92, 168), (214, 122, 40), (63, 143, 79), (138, 79, 160))   # character 0, 1, 2, 3
SKIN_RGB = (233, 196, 160)
NOSE_RGB = (200, 150, 115)
BACKGROUND_TOP, BACKGROUND_FLOOR = (236, 238, 242), (205, 203, 198)
LABEL_RGB = {"PC": (79, 111, 168), "LR": (61, 154, 91), "HP": (217, 164, 65), "PH": (217, 164, 65), "G": (138, 79, 160)}
LABEL_NAMES = {"PC": "phonemic clause", "LR": "listener response", "HP": "hesitation pause",
               "PH": "partner's hesitation", "G": "gesture"}
OTHER_LABEL_RGB = (150, 150, 150)
TICK_RGB = (214, 39, 40)            # synthetic transitions: timeline ticks only, never a body
CURSOR_RGB = (25, 25, 25)
PAGE_RGB = (255, 255, 255)
ROW_RGB = (236, 237, 241)
TEXT_RGB = (40, 40, 40)
MUTED_RGB = (110, 110, 110)

# sizes as fractions of a body's stature
TORSO_RADIUS, LIMB_RADIUS, HEAD_RADIUS, HAND_RADIUS = 0.036, 0.022, 0.068, 0.03
HEAD_LIFT = 0.05          # the head disc's centre above the head joint
