// Flat ring r_in <= r <= R in z = 0 (femshell.mesh.annulus). Curves: outer, inner.
// The slit annulus (annulus(..., slit=True): cut along y = 0, x > 0 with duplicated
// vertices "slit-a"/"slit-b") needs vertex duplication that gmsh does not do: use the
// Python generator for it.
// gmsh -2 -setnumber r_in 0.5 -setnumber R 1 -setnumber h 0.05 annulus.geo -o annulus.msh
DefineConstant[ r_in = 0.5,  // inner radius (design units)
                R = 1.0,     // outer radius
                h = 0.05,    // target edge length
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

Disk(1) = {0, 0, 0, R};
Disk(2) = {0, 0, 0, r_in};
ring() = BooleanDifference{ Surface{1}; Delete; }{ Surface{2}; Delete; };
e = 1e-6 * R;
inner() = Curve In BoundingBox{-r_in - e, -r_in - e, -e, r_in + e, r_in + e, e};
outer() = Curve{:};
outer() -= inner();
Physical Curve("outer") = {outer()};
Physical Curve("inner") = {inner()};
Physical Surface("surface") = {ring()};
