"""The data model every stage shares: what an SSD says once read (`structure`: raw and flattened
systems, connections, parameter values), the `structure.Plan` a run is made from, the FMUs'
model descriptions as records (`fmu`), what a connection does to a value (`transforms`: affine
maps, mapping tables, their chains), physical units (`units`), the communication grid (`grid`)
and a hashable read-only mapping (`frozen`).  Records only: no module here reads a file, imports
fmpy or calls an FMU, so every stage can import them and none imports another stage to know what
a value is.
"""
