"""Input and output formats: WKB in, mesh files (2DM, PLY), 3D models (glTF, OBJ), CityJSON and
number text out."""
