"""Physical constants and the recording roles of a session, defined once for the package.

Column names live in :mod:`imucal.columns`; every default of a setting lives in the config
schema (``workflow/schemas/config.schema.yaml``).
"""

from __future__ import annotations

#: Standard gravity (CGPM 1901), m/s^2: the unit of readers declared in g.
STANDARD_GRAVITY_M_S2 = 9.80665
#: The Earth's sidereal rotation rate (WGS 84), rad/s.
EARTH_RATE_RAD_S = 7.2921150e-5

#: Recording roles of the paper's protocol (the automatic segmentation knows them).
IMU_RECORDINGS = ("rotation3d", "cube", "ratetable", "static")
#: Roles of other protocols found in public recordings: Ferraris (1995) six faces and three
#: 360-degree rotations, Tedaldi (2014) hand-placed poses, free tumbling for ellipsoid fits.
#: Their automatic segments are their static poses.
OTHER_RECORDINGS = ("ferraris", "poses", "tumble")
#: The reference IMU (Xsens MT Manager export).
REFERENCE = "reference"
#: Every recording role, in protocol order.
RECORDING_NAMES = (*IMU_RECORDINGS, REFERENCE, *OTHER_RECORDINGS)

#: Time between the recordings of a simulated session on its session clock, s.
SESSION_GAP_S = 60.0
