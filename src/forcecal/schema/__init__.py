"""The files' declared schemas: the rig file (INTERFACES.md section 1, :mod:`.rig_file`), the
spatial model (:mod:`.model_file`) and the calibration (:mod:`.calibration_file`).

Each file's keys, types, units, bounds and defaults are declared once (pydantic models on
:mod:`.keys`); a document is checked against its schema before anything is built from it, and
every fault is one line naming the file and the dotted key, an unknown key with the nearest
valid one. The readers import the module of their file.
"""
