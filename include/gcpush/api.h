/* gcpush/api.h -- marks the public API.  The library is built with
 * -fvisibility=hidden; every public header wraps its declarations in
 * GCP_API_BEGIN ... GCP_API_END, so that exactly the functions and objects
 * declared there are exported from libgcpush.so, and the private gcp_
 * helpers of the *_priv.h headers stay inside it (tests/cli/test_layers.sh).
 * Without GCC/clang pragmas the markers expand to nothing. */
#ifndef GCPUSH_API_H
#define GCPUSH_API_H

#if defined(__GNUC__) && !defined(__CUDACC__)
#define GCP_API_BEGIN _Pragma("GCC visibility push(default)")
#define GCP_API_END _Pragma("GCC visibility pop")
#else
#define GCP_API_BEGIN
#define GCP_API_END
#endif

#endif /* GCPUSH_API_H */
