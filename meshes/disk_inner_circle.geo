// Flat disk of radius R in z = 0 with the circle r = r_in built into the mesh
// (femshell.mesh.disk with inner_radius; the disk test of design.md section 1.6).
// Curves: outer (r = R, boundary) and inner (r = r_in, an INTERIOR curve of the mesh).
// The size is h_in within h_in of the inner circle and grows with gradient 0.3 to h.
// gmsh -2 -setnumber R 10 -setnumber r_in 3 disk_inner_circle.geo -o disk.msh
DefineConstant[ R = 10.0,    // disk radius (design units)
                r_in = 3.0,  // radius of the inner circle (R2 of the paper)
                h = 1.0,     // target edge length away from the circle
                h_in = 0.5,  // target edge length at the circle (h_in <= h)
                seed = 0 ];
SetFactory("OpenCASCADE");
General.NumThreads = 1;
Mesh.Algorithm = 6;
Mesh.RandomSeed = seed;
Mesh.MeshSizeMin = h_in;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;

Disk(1) = {0, 0, 0, R};
Disk(2) = {0, 0, 0, r_in};
// fragment: the inner disk and the ring share the circle, so mesh edges follow it
BooleanFragments{ Surface{1}; Delete; }{ Surface{2}; Delete; }
e = 1e-6 * R;
inner() = Curve In BoundingBox{-r_in - e, -r_in - e, -e, r_in + e, r_in + e, e};
outer() = Curve{:};
outer() -= inner();

Field[1] = Distance;
Field[1].CurvesList = {inner()};
Field[1].Sampling = Ceil(4 * Pi * r_in / h_in) + 20;   // sample the circle finer than h_in
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = h_in;
Field[2].SizeMax = h;
Field[2].DistMin = h_in;
Field[2].DistMax = h_in + (h - h_in) / 0.3;
Background Field = 2;

Physical Curve("outer") = {outer()};
Physical Curve("inner") = {inner()};
Physical Surface("surface") = Surface{:};
