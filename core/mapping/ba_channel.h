// BaChannel: how the tracker hands bundle-adjustment jobs to a mapping
// side and takes the solved ones back. core/ has no threads: firmware_app
// implements this with a mapping thread (firmware_app/mapping_worker.h),
// tests may implement it synchronously.
//
// Protocol (all calls on the tracking thread, none may block or allocate):
// acquire_job() gives a free job buffer or nullptr when the mapping side
// still holds every buffer (the tracker then defers the job to a later
// frame); submit_job() hands a filled job over; at the start of a frame
// solved_job() returns a solved job not yet applied (or nullptr), which the
// tracker applies to its map and gives back with release_job(). The job
// itself is the versioned snapshot: nothing is shared while it is away.
#pragma once

#include "core/mapping/ba_job.h"

namespace st {

class BaChannel {
 public:
  virtual ~BaChannel() = default;
  virtual BaJob* acquire_job() = 0;
  virtual void submit_job(BaJob* job) = 0;
  virtual const BaJob* solved_job() = 0;
  virtual void release_job(const BaJob* job) = 0;
};

}  // namespace st
