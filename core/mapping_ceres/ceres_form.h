// The Ceres form of the window bundle adjustment: the same problem as the
// Schur solver's (core/mapping/schur_solver.h), built as a ceres::Problem
// and solved by Ceres' dense Schur LM, torn down per solve. The reference
// the Schur solver is tested and benched against (tests/unit/mapping/
// test_ba_schur.cpp, scopetrack-bench ba); not on the product path: the
// programs that track do not link it (core/CMakeLists.txt), so neither
// Ceres nor its sparse-algebra libraries are loaded with them.
//
//   BundleAdjuster ceres;
//   configure_ceres_form(&ceres, options, mesh, K, max_kf, max_pts, max_obs);
//   ceres.solve(&job);  // allocates inside Ceres, bounded by the job's size
#pragma once

#include "core/base/result.h"
#include "core/geometry/camera.h"
#include "core/mapping/ba_options.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/mesh/mesh.h"

namespace st {

// Configures ba (BundleAdjuster::configure) and has it solve with the
// Ceres form from then on. The cost-function objects are pooled for the
// maxima; Ceres allocates its Problem, Program and linear-solver workspace
// on every solve.
Status configure_ceres_form(BundleAdjuster* ba, const BundleAdjusterOptions& options, const Mesh& mesh,
                            const Pinhole& K, int max_keyframes, int max_points, int max_observations);

}  // namespace st
