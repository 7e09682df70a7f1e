/* gcpush/gcpush.h -- umbrella header of the gcpush library. */
#ifndef GCPUSH_GCPUSH_H
#define GCPUSH_GCPUSH_H

#include "error.h"
#include "field.h"
#include "io.h"
#include "kernels.h"
#include "particles.h"
#include "pusher.h"
#include "run.h"
#include "section.h"
#include "units.h"

#endif
