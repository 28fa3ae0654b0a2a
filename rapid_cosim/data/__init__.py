"""Measurements in, masked and on a time base.

``measured`` holds a recording in memory (:class:`MeasuredData`: time, columns, masks,
gaps, resampling); ``readers`` reads one from a file (CSV, MAT, HDF5), ``comtrade`` and
``pmu`` the recorders' formats; ``noise`` estimates its noise level.
"""

from .measured import (Gap, MaskedSamplesWarning, MeasuredData, MissingColumn, close_matches, describe_missing,
                       sample_onto)
from .noise import MIN_NOISE_SAMPLES, NoiseEstimate, ar1_inflation, noise_level
from .readers import CSV_SUFFIXES, HDF5_SUFFIXES, MAT_SUFFIXES, load_measurements, split_hdf5_path

__all__ = ["Gap", "MaskedSamplesWarning", "MeasuredData", "MissingColumn", "close_matches", "describe_missing",
           "sample_onto", "MIN_NOISE_SAMPLES", "NoiseEstimate", "ar1_inflation", "noise_level", "CSV_SUFFIXES",
           "HDF5_SUFFIXES", "MAT_SUFFIXES", "load_measurements", "split_hdf5_path"]
