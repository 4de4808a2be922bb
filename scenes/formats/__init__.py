"""File formats in and out: glTF 2.0 read and write, the ``export`` folder, camera sequence
files, and the resolution of a command's scene argument to a loaded scene (:mod:`.inputs`)."""
