// The GPU buffer's header (nrad.h "GPU buffers", docs/runtime.md): its magic, its size and the word offset of each
// field, defined once for the runtime's packer (runtime/src/gpu_buffer.cpp) and for nrad.glsl, which both
// include it. Written in the common subset of C, C++ and GLSL (macros and uint literals only). Installed
// beside nrad.glsl (share/nrad/shaders); where a toolchain has no includes, paste it before nrad.glsl.
#ifndef NRAD_GPU_LAYOUT_H
#define NRAD_GPU_LAYOUT_H

#define NRAD_GPU_MAGIC 0x5047524Eu  // "NRGP"
#define NRAD_GPU_HEADER_WORDS 64u   // the header's words; the cell table starts after them

// Word offsets of the header's fields (three words from LOWER, UPPER, DIMS and FACTOR; eight from HIDDEN_WIDTHS).
#define NRAD_GPU_WORD_MAGIC 0u
#define NRAD_GPU_WORD_VERSION 1u
#define NRAD_GPU_WORD_CONTENT_FLAGS 2u
#define NRAD_GPU_WORD_OUTPUT_TRANSFORM 3u
#define NRAD_GPU_WORD_LOWER 4u
#define NRAD_GPU_WORD_UPPER 7u
#define NRAD_GPU_WORD_DIMS 10u
#define NRAD_GPU_WORD_FACTOR 13u
#define NRAD_GPU_WORD_BAND 16u
#define NRAD_GPU_WORD_HIDDEN_LAYERS 17u
#define NRAD_GPU_WORD_HIDDEN_WIDTHS 18u
#define NRAD_GPU_WORD_PARAMS 26u
#define NRAD_GPU_WORD_NETWORKS 27u
#define NRAD_GPU_WORD_CELLS 28u
#define NRAD_GPU_WORD_TREE_NODES 29u
// The sections' word offsets in the buffer.
#define NRAD_GPU_WORD_CELL_TABLE 30u
#define NRAD_GPU_WORD_SCALES 31u
#define NRAD_GPU_WORD_NODES 32u
#define NRAD_GPU_WORD_WIDTHS 33u
#define NRAD_GPU_WORD_BOXES 34u
#define NRAD_GPU_WORD_WEIGHTS 35u
#define NRAD_GPU_WORD_TOTAL 36u
// The light in the volume (format 2.4's VVOX/VWGT; all 0 for an asset without it): its networks' count, then the
// word offsets of its cell -> network table, its output scales and its fp16 weights (laid out as the surfaces').
#define NRAD_GPU_WORD_VOLUME_NETWORKS 37u
#define NRAD_GPU_WORD_VOLUME_CELL_TABLE 38u
#define NRAD_GPU_WORD_VOLUME_SCALES 39u
#define NRAD_GPU_WORD_VOLUME_WEIGHTS 40u
// How the volume's networks decode (layout version 2; format 2.6's kFlagVolumeExponential): 0 or 1 as
// NRAD_GPU_WORD_OUTPUT_TRANSFORM (0 without volume networks).
#define NRAD_GPU_WORD_VOLUME_OUTPUT_TRANSFORM 41u

// A tree node's first word is `axis | split << 2` (the file's TREE record); this axis marks a leaf.
#define NRAD_GPU_TREE_LEAF 3u

#endif  // NRAD_GPU_LAYOUT_H
