"""Calibration of a partial session: run every stage the recordings allow, say why not the rest.

Public recordings rarely follow the paper's whole protocol (3-D platform, 12-position cube, rate
table, reference). This package decides, from the recordings, the sensors they hold and their
segments, which methods can run, runs them in dependency order and records every stage as
``run`` or ``skipped`` with the reason. A stage that applies but cannot be fitted from these data
(too few poses, a direction not excited, ...) is skipped with the fit's own message, so a partial
session never fails as a whole; errors that are not about the data (bugs) still propagate.
Where the recordings give the sensors' ranges (raw counts and ``range_counts``), readings at a
range are clipped: the cube fit and the rate table leave them out, and the gyroscope fits that
integrate turns (known rotations, pose to pose) leave out the turns that hold one.

Methods per sensor, best first (the first that runs gives the final calibration):

- magnetometer: ellipsoid fit (step 1) + ``T_R,mag`` from the rotation3d phases (step 2); step 1
  alone leaves the field in the magnetometer's own (ellipsoid) frame;
- accelerometer: known orientations (six faces, Ferraris) in frame B of the positions; cube fit
  (eq. 32) on many static poses + ``T_R,acc`` from the rotation3d phases; the gravity direction
  of an orientation reference at rests (in the gyroscope's frame); the cube fit alone;
- gyroscope: rate table (eq. 33) + ``T_R,gyr``; known-angle rotations (Ferraris); against an
  orientation reference (motion capture, robot); pose to pose (Tedaldi et al. 2014) in the
  accelerometer's frame; tool-free (``T_R,gyr`` + eq. 36 scale);
  the bias alone.

The runners of each sensor live in :mod:`.magnetometer`, :mod:`.accelerometer` and
:mod:`.gyroscope`, each with its condition and reason when it does not apply; each reads the
session (:mod:`.session`: its recordings, segments, references and the
:class:`~imucal.pipeline.options.PipelineOptions` built as the other chains build theirs) and
the artifacts of the earlier stages it needs, passed as its node's inputs. :mod:`.driver` makes
them nodes of the stage graph, runs them with the graph's runner and chooses the final
calibration; :mod:`.listing` gives the stage listing, ``calibration.json``, the artifacts per
sensor and the figures. The public names are re-exported here.
"""

from imucal.pipeline.outcome import NotApplicable
from imucal.pipeline.partial.driver import (
    READS,
    RUNNERS,
    calibrate_partial,
    calibration_of,
    final_calibration,
    review,
    run_stages,
)
from imucal.pipeline.partial.gyroscope import (
    ADJACENT_SAMPLES,
    pose_direction_covariance,
    pose_intervals,
    rest_to_rest,
)
from imucal.pipeline.partial.listing import (
    PartialFiles,
    calibration_file,
    figures,
    full_protocol_stages,
    stage_results,
)
from imucal.pipeline.partial.session import Outcome, Session, session_of, session_options
from imucal.pipeline.stages.accelerometer import MIN_CUBE_POSITIONS
from imucal.pipeline.stages.common import sensors_of
from imucal.pipeline.stages.magnetometer import MAG_RECORDINGS, ONE_ORIENTATION

__all__ = [
    "ADJACENT_SAMPLES",
    "MAG_RECORDINGS",
    "MIN_CUBE_POSITIONS",
    "NotApplicable",
    "ONE_ORIENTATION",
    "Outcome",
    "PartialFiles",
    "READS",
    "RUNNERS",
    "Session",
    "calibrate_partial",
    "calibration_file",
    "calibration_of",
    "figures",
    "final_calibration",
    "full_protocol_stages",
    "pose_direction_covariance",
    "pose_intervals",
    "rest_to_rest",
    "review",
    "run_stages",
    "sensors_of",
    "session_of",
    "session_options",
    "stage_results",
]
