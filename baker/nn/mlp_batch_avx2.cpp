// Mlp's mini-batch kernels with AVX2 (compiled with -mavx2, no FMA: the same bits as mlp_batch_sse2.cpp).
#define NRAD_MLP_KERNELS mlp_avx2
#include "baker/nn/mlp_batch_impl.h"

