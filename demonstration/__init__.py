"""The demonstration world: a simulated person (several bodies) moving a block on their own table,
what motion capture adds to it, the recordings it makes and their HDF5 file format."""
