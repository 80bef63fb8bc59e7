// Flat rectangle [0, lx] x [0, ly] in z = 0 (femshell.mesh.plate, femshell.mesh.strip).
// Boundary curves (physical groups): left (x = 0), right (x = lx), bottom (y = 0), top (y = ly).
// gmsh -2 -setnumber lx 2 -setnumber h 0.05 plate.geo -o plate.msh
DefineConstant[ lx = 1.0,    // length along x (design units)
                ly = 1.0,    // length along y
                h = 0.1,     // target edge length
                seed = 0 ];
SetFactory("OpenCASCADE");
General.NumThreads = 1;
Mesh.Algorithm = 6;
Mesh.RandomSeed = seed;
Mesh.MeshSizeMin = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;

Rectangle(1) = {0, 0, 0, lx, ly};
e = 1e-6 * (lx + ly);
Physical Curve("left") = Curve In BoundingBox{-e, -e, -e, e, ly + e, e};
Physical Curve("right") = Curve In BoundingBox{lx - e, -e, -e, lx + e, ly + e, e};
Physical Curve("bottom") = Curve In BoundingBox{-e, -e, -e, lx + e, e, e};
Physical Curve("top") = Curve In BoundingBox{-e, ly - e, -e, lx + e, ly + e, e};
Physical Surface("surface") = {1};
