/* gcpush/gcpush.h -- umbrella header of the gcpush library: everything a
 * PIC code or an embedding program needs, free of MPI and HDF5 headers
 * (grid_file.h reads and writes HDF5 grid files without them).  The
 * output layer (HDF5 files, MPI ranks) is apart: #include <gcpush/io.h>,
 * which needs mpi.h on the include path. */
#ifndef GCPUSH_GCPUSH_H
#define GCPUSH_GCPUSH_H

#include "error.h"
#include "field.h"
#include "gc.h"
#include "grid.h"
#include "grid_file.h"
#include "invariants.h"
#include "kernels.h"
#include "particles.h"
#include "pusher.h"
#include "results.h"
#include "run.h"
#include "section.h"
#include "sweep.h"
#include "units.h"

#endif
