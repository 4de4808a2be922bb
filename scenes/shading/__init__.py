"""The shading models and their material data: Lambert diffuse with Blinn-Phong specular and
the receiver rule (:mod:`.phong`), the glTF 2.0 metallic-roughness BRDF (:mod:`.pbr`) and the
materials both read (:mod:`.materials`: the diffuse dictionary, glTF factors and textures)."""
