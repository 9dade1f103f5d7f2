"""Reading: files a user brings become values of `cosim.model`.  An SSD, a folder or an ``.ssp``
archive is read (`ssp`, its parameter sets and ``.ssm`` mappings with `mapping`) and flattened into
one level of components (`flatten`); each component's FMU is found (`resources`), checked as a run
will load it (`loadable`), unpacked once per content (`fmucache`) and its model description read
into our own records (`description`, the one reader that uses fmpy's parser).  Untrusted text is
data here: XML without entities, archives within limits (`cosim.safeio`).
"""
