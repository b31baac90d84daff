// The one translation unit that compiles tinygltf's implementation, with Draco on. The image decoders
// (stb_image) come from Debian's libstb, so no STB_*_IMPLEMENTATION here. Every file that includes
// tiny_gltf.h is built with the same TINYGLTF_* definitions (see baker/CMakeLists.txt).
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
