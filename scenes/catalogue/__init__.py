"""The built-in scenes: the catalogue (:mod:`.builtin`), the scene families (shadow, AA, moving,
glTF/PBR, scale) and the dict factories the families are written with."""
