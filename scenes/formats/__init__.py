"""File formats in and out: glTF 2.0 read and write, the ``export`` folder and camera sequence
files (a command's scene argument is resolved above them, in :mod:`scenes.inputs`)."""
