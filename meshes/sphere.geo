// Closed sphere of radius R centred at the origin (femshell.mesh.sphere).
// Parameters (override with  gmsh -2 -setnumber R 30 -setnumber h 2.2 sphere.geo -o sphere.msh):
DefineConstant[ R = 1.0,     // radius (design units)
                h = 0.1,     // target edge length
                seed = 0 ];  // Mesh.RandomSeed: same seed, same mesh
// femshell.mesh.edge_length_for_vertices(n, 4*Pi*R^2, 4.96*R) converts a vertex count to h.
SetFactory("OpenCASCADE");
General.NumThreads = 1;            // one thread: reproducible meshes
Mesh.Algorithm = 6;                // Frontal-Delaunay
Mesh.RandomSeed = seed;
Mesh.MeshSizeMin = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;

Sphere(1) = {0, 0, 0, R};
Physical Surface("surface") = Surface{:};
