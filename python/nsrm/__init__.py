"""nsrm — camera colour correction from Python.

Fits linear (LRM), polynomial (PRM), root-polynomial (RPRM) and normalised-signal polynomial
(NSRM) models mapping linear camera RGB to CIE XYZ, applies them per pixel on the CPU or the GPU,
evaluates them (leave-one-out ΔE00), reads colour charts in photographs and exports LUTs and
profiles. Every function calls the Rust library ``nsrm`` (the same code as the ``nsrm`` command
line); the work runs with the GIL released.

>>> import nsrm
>>> data = nsrm.builtin_training("nikon-d5100", "D65")
>>> model = nsrm.fit(data["camera_rgb"], data["xyz"], "nsrm", 3, white=data["white_xyz"])
>>> xyz = model.apply(data["camera_rgb"])          # float32, as `nsrm apply` writes
"""

from ._nsrm import (
    GpuUnavailableError,
    InputError,
    Model,
    NsrmError,
    __version__,
    builtin_training,
    delta_e00,
    eval_loo,
    export,
    fit,
    read_chart,
    read_frame,
)

__all__ = [
    "GpuUnavailableError",
    "InputError",
    "Model",
    "NsrmError",
    "__version__",
    "builtin_training",
    "delta_e00",
    "eval_loo",
    "export",
    "fit",
    "read_chart",
    "read_frame",
]
