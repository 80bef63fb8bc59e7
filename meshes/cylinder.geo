// Open cylinder x^2 + y^2 = R^2, 0 <= z <= L, no caps (femshell.mesh.cylinder).
// full = 1: the whole cylinder, curves bottom (z = 0) and top (z = L).
// full = 0: the panel t0 <= theta <= t1 (radians), also side-a (theta = t0), side-b (theta = t1).
// femshell orients normals away from the axis; a mesh made here keeps gmsh's orientation.
// gmsh -2 -setnumber full 0 -setnumber t1 1.5 cylinder.geo -o panel.msh
DefineConstant[ R = 1.0,     // radius (design units)
                L = 2.0,     // length along z
                h = 0.1,     // target edge length
                full = 1,    // 1: full cylinder, 0: panel
                t0 = 0.0,    // panel start angle (radians)
                t1 = 1.0,    // panel end angle, 0 < t1 - t0 < 2 Pi
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

If (full)
  Circle(1) = {0, 0, 0, R};
Else
  Circle(1) = {0, 0, 0, R, t0, t1};
EndIf
// sweeping the circle (arc) along z gives the lateral surface only
side[] = Extrude{0, 0, L}{ Curve{1}; };
e = 1e-6 * (R + L);
Physical Curve("bottom") = Curve In BoundingBox{-R - e, -R - e, -e, R + e, R + e, e};
Physical Curve("top") = Curve In BoundingBox{-R - e, -R - e, L - e, R + e, R + e, L + e};
If (!full)
  xa = R * Cos(t0); ya = R * Sin(t0);
  xb = R * Cos(t1); yb = R * Sin(t1);
  Physical Curve("side-a") = Curve In BoundingBox{xa - e, ya - e, -e, xa + e, ya + e, L + e};
  Physical Curve("side-b") = Curve In BoundingBox{xb - e, yb - e, -e, xb + e, yb + e, L + e};
EndIf
Physical Surface("surface") = {side[1]};
