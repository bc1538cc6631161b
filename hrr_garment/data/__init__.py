"""File formats (the dataset HDF5, out.h5), training windows and the importer."""
