"""Readers of the formats labs record in, each returning one :class:`~optikin.data.recording.Recording`.

=====================  ==========================================  ======================================
source (``recordings``)  module                                  reads
=====================  ==========================================  ======================================
``motive``             :mod:`optikin.data.readers.motive_csv`      OptiTrack Motive CSV exports
``c3d``                :mod:`optikin.data.readers.c3d`             C3D files (needs ``optikin[c3d]``)
``rosbag``             :mod:`optikin.data.readers.rosbag`          ROS 2 bags (needs ``optikin[rosbag]``)
``csv``                :mod:`optikin.data.readers.plain_csv`       plain CSV with a column mapping
=====================  ==========================================  ======================================

Importing this package registers the four sources of data family ``recordings``
(:mod:`optikin.data.sources`); the optional dependencies are imported only when a
file is read. Shared params and steps: :mod:`optikin.data.readers.common`.
"""

from optikin.data.readers.c3d import read_c3d
from optikin.data.readers.common import FAMILY, RecordingParams
from optikin.data.readers.motive_csv import read_motive_csv
from optikin.data.readers.plain_csv import PlainCsvParams, read_plain_csv
from optikin.data.readers.rosbag import RosbagParams, read_rosbag

__all__ = [
    "FAMILY",
    "PlainCsvParams",
    "RecordingParams",
    "RosbagParams",
    "read_c3d",
    "read_motive_csv",
    "read_plain_csv",
    "read_rosbag",
]
