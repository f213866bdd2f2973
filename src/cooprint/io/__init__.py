"""File input and output: meshes in, bundles out."""
