"""The data layer: every dataset's demonstrations in one clean, documented form.

>>> from clfd_bench.data import load_dataset
>>> ds = load_dataset("robotasks", order=0)
>>> ds.task_names
['openbox', 'bottle2shelf', 'platestandingtolying', 'pouring']
>>> ds[0].demos.shape  # [N, T, D]: position (m) + quaternion (w, x, y, z)
(9, 1000, 7)

See :mod:`clfd_bench.data.sources` for where files come from (``CLFD_DATA_DIR``, the
download cache) and :class:`Task` for units and shapes.
"""

from clfd_bench.data.loaders import (
    DATASETS,
    LASA_SIM_SCALE,
    CorruptDatasetError,
    list_datasets,
    load_dataset,
    load_task,
)
from clfd_bench.data.orders import TASK_ORDERS
from clfd_bench.data.sources import ChecksumError, DatasetError, DatasetUnavailableError
from clfd_bench.data.types import Dataset, Task

__all__ = [
    "DATASETS",
    "LASA_SIM_SCALE",
    "TASK_ORDERS",
    "ChecksumError",
    "CorruptDatasetError",
    "Dataset",
    "DatasetError",
    "DatasetUnavailableError",
    "Task",
    "list_datasets",
    "load_dataset",
    "load_task",
]
