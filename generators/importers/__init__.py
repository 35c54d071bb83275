"""Importers of other tools' trajectories into H5MD sims (`graphdem import`, docs/import.md): GNS .npz
(gns.py), LagrangeBench HDF5 (lagrangebench.py) and LAMMPS text dumps (lammps_dump.py), the items a user gives
for what a source lacks (metadata.py) and the sims and folder written from them (sims.py)."""
