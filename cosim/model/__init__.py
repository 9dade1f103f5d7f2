"""The data model every stage shares: what an SSD says once read (`structure`: raw and flattened
systems, connections, parameter values), the `structure.Plan` a run is made from, physical units and
the affine maps between them (`units`), and the communication grid (`grid`).  Records only: no
module here reads a file, imports fmpy or calls an FMU, so every stage can import them and none
imports another stage to know what a value is.
"""
