// The lockstep training step with AVX2 and FMA (compiled with -mavx2 -mfma -ffp-contract=off: the same bits as the
// plain lanes of mlp_lockstep.cpp).
#define NRAD_LOCKSTEP_KERNELS lockstep_avx2
#include "baker/nn/mlp_lockstep_impl.h"
