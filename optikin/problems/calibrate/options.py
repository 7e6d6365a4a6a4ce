"""The ``options`` of a ``calibrate`` problem file: what is estimated, the robust loss, outliers, the held-out test."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, StrictFloat, StrictInt

from optikin.options import Options

BaseComponent = Literal["x", "y", "z", "tilt", "yaw"]
Axis = Literal["x", "y", "z"]


class BaseOptions(Options):
    """The base: a tracked rigid body (``body``), a mount plane and exit direction (``plane``, ``direction``), a
    pose (``position``, ``orientation``, held with ``fix``) or, with none of them, estimated from several starts
    (``starts``); priors and components held."""

    position: list[StrictFloat] | None = Field(
        None, min_length=3, max_length=3, description="starting base position [m] in the recording frame"
    )
    orientation: list[StrictFloat] | None = Field(
        None,
        min_length=4,
        max_length=4,
        description="starting base orientation, unit quaternion (w, x, y, z) in the recording frame "
        "(its z axis along the unbent backbone)",
    )
    body: str | None = Field(
        None,
        description="a rigid body of the recording at the base: its mean pose is the start (instead of "
        "position and orientation); its x axis then fixes the rotation about the base axis",
    )
    position_sigma: StrictFloat | None = Field(None, gt=0, description="std of a prior at the start position [m]")
    orientation_sigma_deg: StrictFloat | None = Field(
        None, gt=0, description="std of a prior at the start orientation [deg]"
    )
    plane: dict[Axis, StrictFloat] | None = Field(
        None,
        description="the mount plane as one coordinate along an axis of the recording's frame, in metres, e.g. "
        "{y: 0.0}: the base stays on it (its position in the plane is estimated)",
    )
    direction: list[StrictFloat] | None = Field(
        None,
        min_length=3,
        max_length=3,
        description="the direction the backbone leaves the base, in the recording's frame (e.g. [0, -1, 0]: "
        "hanging, y up): the base axis, held",
    )
    starts: Literal["several", "data"] = Field(
        "several",
        description="where the base is estimated (no body, plane, direction, position or orientation): several "
        "starts (the base axis from the data, hanging down, standing up), the best by held-out error, all "
        "reported; or the start from the data alone",
    )
    fix: list[BaseComponent] = Field(default_factory=list, description="components held at their start")
    estimate_yaw: bool = Field(
        False, description="estimate the rotation about the base axis (not observable from positions alone)"
    )


class HoldOutOptions(Options):
    """How the held-out error is measured."""

    method: Literal["kfold", "split"] = Field("kfold", description="k-fold cross-validation or one train/test split")
    folds: StrictInt = Field(5, ge=2, le=50, description="folds of kfold")
    test_fraction: StrictFloat = Field(0.2, gt=0, lt=1, description="share of postures tested by split")


class IdentifiabilityOptions(Options):
    """When the geometry counts as determined (:mod:`optikin.calibration.identifiability`)."""

    max_std: StrictFloat = Field(
        1.0, gt=0, description="largest standard deviation of a parameter or combination [mm; angles: deg]"
    )


class CalibrateOptions(Options):
    """Options of kind ``calibrate``."""

    markers: dict[str, StrictInt] | None = Field(
        None,
        description="marker name -> 1-based section whose end disk carries it; "
        "default: the recording's markers in order, one per section",
    )
    lengths: Literal["estimate", "fixed", "extensible"] = Field(
        "estimate",
        description="estimate shared section lengths (start: the arm's section_lengths), hold them, "
        "or fit one length per section and posture (extensible arm: the ranges are reported)",
    )
    base: BaseOptions = Field(default_factory=BaseOptions)
    actuator_map: Literal["none", "linear"] = Field(
        "none",
        description="linear: every posture's bending vectors are a linear map of its actuator readings, estimated "
        "with the geometry (no per-posture unknowns; the held-out error is then a prediction from the readings)",
    )
    actuators: list[str] | None = Field(
        None, description="the actuator channels of the map (default: every channel of the recording)"
    )
    offsets: Literal["none", "per_marker"] = Field(
        "none", description="estimate one offset per marker from its disk's centre, in the disk's frame"
    )
    offset_sigma: StrictFloat | None = Field(None, gt=0, description="std of a zero-mean prior on the offsets [m]")
    loss: Literal["soft_l1", "huber", "linear"] = Field(
        "soft_l1",
        description="loss on marker errors where the geometry is estimated (every reported error is least squares)",
    )
    loss_scale: StrictFloat = Field(1e-3, gt=0, description="scale of the robust loss [m]")
    marker_noise: StrictFloat = Field(
        3e-4, gt=0, description="expected marker noise per coordinate [m], weighing the priors against the data"
    )
    outlier_threshold: StrictFloat = Field(
        6.0,
        gt=1,
        description="a posture with a marker error above this many median marker errors is rejected from the "
        "geometry's fit; in the held-out test the rule is applied inside each training fold (the test postures "
        "beyond it are reported apart, and still counted)",
    )
    holdout: HoldOutOptions = Field(default_factory=HoldOutOptions)
    identifiability: IdentifiabilityOptions = Field(default_factory=IdentifiabilityOptions)
    max_iterations: StrictInt = Field(100, ge=1, description="Levenberg-Marquardt steps per fit")
    tolerance: StrictFloat = Field(1e-10, gt=0, description="relative decrease of the cost that ends a fit")
    arm_file: str | None = Field(
        None, description="write the calibrated arm section to this YAML file (relative to the problem file)"
    )
    targets_file: str | None = Field(
        None,
        description="write the kept postures' tip marker in the calibrated base frame to this CSV file "
        "(t, x, y, z: targets of kind ik, source csv), relative to the problem file",
    )
    points_file: str | None = Field(
        None,
        description="write the kept postures' measured points in the recording frame to this CSV file "
        "(<marker>_x, _y, _z: point targets of kind ik, source csv, with the calibrated base pose as "
        "data.params.base), relative to the problem file",
    )
    folds_file: str | None = Field(
        None,
        description="write the held-out test's fold of every posture to this CSV file (posture, fold), relative "
        "to the problem file (the array fold of arrays.npz holds the same)",
    )
    markers_file: str | None = Field(
        None,
        description="write the kept postures as end poses of the calibrated arm with the other markers "
        "to this CSV file (kind ph_shape, source csv), relative to the problem file",
    )
