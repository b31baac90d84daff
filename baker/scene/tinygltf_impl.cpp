// The one translation unit that compiles tinygltf's implementation, without its Draco path: the importer
// decodes KHR_draco_mesh_compression itself (gltf_loader.cpp), because tinygltf's Draco code indexes the
// file's buffers, views and attributes unchecked. The image decoders (stb_image) come from Debian's libstb,
// so no STB_*_IMPLEMENTATION here. Every file that includes tiny_gltf.h is built with the same TINYGLTF_*
// definitions (see baker/scene/CMakeLists.txt).
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
