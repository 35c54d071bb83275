"""LAMMPS driver: input templates run with `-var` parameters, dump and log parsing."""
