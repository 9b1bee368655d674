// Mesh simplification for the tracker's per-frame rasteriser.
//
// A CT or MRI segmentation exported as it is (marching cubes) often holds
// hundreds of thousands of triangles, while the tracker renders the organ
// every frame for its mask and depth: the render's cost grows with the
// triangle count (320k triangles: ~8x the 20k liver's). Vertex clustering
// (Rossignac and Borrel's method): the vertices are binned into a uniform
// grid of cubic cells, and within a cell by the nearest of six axis
// directions to their normal (the two sides of a part thinner than a cell
// stay apart); every cluster becomes one vertex, placed at the point
// nearest the planes of its triangles (area-weighted plane quadrics, as
// Lindstrom's out-of-core simplification does), and a triangle survives if
// its three corners land in three different clusters, with its winding
// kept (outward normals stay outward). Triangles that become the same one
// are kept once. Any triangle soup works: no manifold or closed input is
// needed, so a real segmentation cannot make it fail.
//
// On a smooth organ surface the merged vertices stay within a small
// fraction of the cell size of the original surface (a cell spans a nearly
// flat patch); tests/test_mesh_simplify.cpp measures it on the CT liver.
//
// Start-up code (configure time): allocates freely.
#pragma once

#include "core/mesh/mesh.h"
#include "core/base/result.h"

namespace st {

struct SimplifyReport {
  int input_triangles = 0;
  int output_triangles = 0;
  int output_vertices = 0;
  double cell_mm = 0;  // the grid's cell size; 0 when the mesh was already within budget
  int passes = 0;      // clustering passes run to meet the budget
};

// One clustering pass at the given cell size (> 0, finite). Vertices not
// used by any triangle are dropped.
Result<Mesh> cluster_vertices(const Mesh& mesh, double cell_mm);

// The mesh itself if it holds at most max_triangles; else clustered with the
// first cell size that brings it within budget, from a geometric series of
// factor 1.15 starting a little below the cell the surface area predicts.
// Errors: an empty mesh, max_triangles < 16, non-finite vertices.
Result<Mesh> simplify_to_budget(const Mesh& mesh, int max_triangles, SimplifyReport* report = nullptr);

}  // namespace st
