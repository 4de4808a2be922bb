"""The shading models: Lambert diffuse with Blinn-Phong specular and the receiver rule
(:mod:`.phong`), and the glTF 2.0 metallic-roughness BRDF (:mod:`.pbr`)."""
