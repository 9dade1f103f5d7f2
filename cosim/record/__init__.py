"""Recording: the rows a run produces become files.  One `observers.Observer` role fans the rows
out to memory, CSV (`csvformat`, the bytes Arrow writes) and Parquet sinks with the run's metadata
JSON, through a memory-mapped journal (`journal`) that a crash does not lose; `outputs` checks
every output path before anything is instantiated and `results` reads result files back.
"""
