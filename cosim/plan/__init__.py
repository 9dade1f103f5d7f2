"""Planning: a flattened system and its FMUs' descriptions become the `cosim.model.structure.Plan`,
everything a run needs and nothing it must look up again.  `build` checks connectors, connections
and root outputs against the FMUs, with the parameter values (`parameters`), the unit conversions
and transformations of every connection (`routing`), the Model Exchange solver
settings (`solvers`) and the evaluation order from the connection graph (`graph`); `inputs` binds an
input table to the plan's inputs and `single` prepares a run of one FMU or a system with what the
command line adds.  Nothing here instantiates an FMU.
"""
