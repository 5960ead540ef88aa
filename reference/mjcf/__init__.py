"""MJCF files as reference Models: what a file may hold (checks) and the model built from
MuJoCo's compiled numbers (loader)."""
