"""The array and path types the package's signatures use, named once for every module."""

from __future__ import annotations

import os
from typing import Union

import numpy as np
import numpy.typing as npt

__all__ = ["B", "F32", "F64", "I64", "PathLike"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
B = npt.NDArray[np.bool_]
#: A file or folder name, as ``open`` takes it.
PathLike = Union[str, "os.PathLike[str]"]
