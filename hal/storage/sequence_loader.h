// Loads a sequence folder (docs sequence-format.md): sequence.yaml, the
// mesh (validated, winding fixed), the video header, and the optional
// ground truth and markers. Load time only: allocates freely. The video is
// not read here beyond its header: open it with Y4mReader to stream it.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/mesh/mesh.h"
#include "core/formats/mesh_io.h"
#include "core/base/result.h"
#include "core/formats/sequence.h"
#include "core/formats/trajectory.h"
#include "core/formats/y4m.h"

namespace st {

struct LoadedSequence {
  std::filesystem::path dir;
  SequenceConfig config;
  Mesh mesh;                    // outward winding
  MeshReport mesh_report;
  Y4mHeader video_header;
  std::filesystem::path video_path, mesh_path;
  bool video_is_pipe = false;   // a FIFO: the header was not read (reading would consume it)
  std::vector<TimedPose> groundtruth;  // empty when the sequence has none
  std::vector<Marker> markers;         // empty when the sequence has none
};

// Errors name the file and what is wrong: a missing referenced file, an
// invalid mesh, a video whose size differs from the calibration, etc.
Result<LoadedSequence> load_sequence(const std::filesystem::path& dir);

// Reads and parses only the Y4M header of a file (the first line).
Result<Y4mHeader> read_y4m_file_header(const std::filesystem::path& path);

// Writes sequence.yaml (+ groundtruth/markers when given) into dir; the
// video and mesh are written by their own writers.
Status write_sequence_files(const std::filesystem::path& dir, const SequenceConfig& config,
                            const std::vector<TimedPose>* groundtruth = nullptr,
                            const std::vector<Marker>* markers = nullptr);

}  // namespace st
