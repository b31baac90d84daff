// Mlp's mini-batch kernels on the baseline instruction set (SSE2 on x86-64, plain loops elsewhere).
#define NRAD_MLP_KERNELS mlp_sse2
#include "baker/nn/mlp_batch_impl.h"

