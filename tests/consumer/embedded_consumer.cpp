// Consumer of a kernel embedded with skintune_embed_kernels: no skintune
// library, only the generated header (tuned_kernels.h), plain OpenCL and the
// program's own glTF loading (tinygltf). Skins CesiumMan with the palette in
// PALETTE (joints x 16 float32, from `skintune skin --palette-out`) on PoCL and
// writes the positions as a skintune .stv file for the test to check.
//   consumer_embedded MODEL.gltf PALETTE.bin OUT.stv
#include <tiny_gltf.h>  // Debian's libtinygltf (a shared library: no implementation define here)

#include <CL/cl.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tuned_kernels.h"

namespace {

[[noreturn]] void Die(const std::string& message) {
  std::fprintf(stderr, "consumer_embedded: %s\n", message.c_str());
  std::exit(1);
}

void Check(cl_int err, const char* call) {
  if (err != CL_SUCCESS) Die(std::string(call) + " failed: " + std::to_string(err));
}

// Component c of element i of a glTF accessor, as a double (floats, or unsigned ints for joints).
double Component(const tinygltf::Model& m, int accessor_index, std::size_t i, int c) {
  const tinygltf::Accessor& a = m.accessors.at(accessor_index);
  const tinygltf::BufferView& view = m.bufferViews.at(a.bufferView);
  const int size = tinygltf::GetComponentSizeInBytes(a.componentType);
  const int count = tinygltf::GetNumComponentsInType(a.type);
  const std::size_t stride = view.byteStride ? view.byteStride : std::size_t(size) * count;
  const unsigned char* p = m.buffers.at(view.buffer).data.data() + view.byteOffset + a.byteOffset + i * stride + c * size;
  switch (a.componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { std::uint16_t u; std::memcpy(&u, p, 2); return u; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return *p;
    default: Die("unsupported accessor component type " + std::to_string(a.componentType));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) Die("usage: consumer_embedded MODEL.gltf PALETTE.bin OUT.stv");
  tinygltf::Model gltf;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  if (!loader.LoadASCIIFromFile(&gltf, &error, &warning, argv[1])) Die(std::string(argv[1]) + ": " + error);
  const tinygltf::Primitive& primitive = gltf.meshes.at(0).primitives.at(0);
  const int position = primitive.attributes.at("POSITION"), joint = primitive.attributes.at("JOINTS_0"),
            weight = primitive.attributes.at("WEIGHTS_0");
  const std::size_t n = gltf.accessors.at(position).count;
  const int joint_count = static_cast<int>(gltf.skins.at(0).joints.size());
  std::vector<float> positions(n * 3), weights(n * 4);
  std::vector<std::uint32_t> joints(n * 4);
  for (std::size_t v = 0; v < n; ++v) {
    for (int c = 0; c < 3; ++c) positions[v * 3 + c] = float(Component(gltf, position, v, c));
    double sum = 0.0;
    for (int i = 0; i < 4; ++i) {
      joints[v * 4 + i] = std::uint32_t(Component(gltf, joint, v, i));
      sum += weights[v * 4 + i] = float(Component(gltf, weight, v, i));
    }
    if (std::abs(sum - 1.0) > 1e-3)  // renormalise weights that are off, as glTF asks of loaders
      for (int i = 0; i < 4; ++i) weights[v * 4 + i] = float(weights[v * 4 + i] / sum);
  }
  std::ifstream palette_file(argv[2], std::ios::binary);
  const std::vector<char> palette_bytes((std::istreambuf_iterator<char>(palette_file)), {});
  if (palette_bytes.size() != std::size_t(joint_count) * 64) Die(std::string(argv[2]) + ": not a palette of the skin");
  std::vector<float> matrices(palette_bytes.size() / 4);
  std::memcpy(matrices.data(), palette_bytes.data(), palette_bytes.size());

  // The tuned kernel for 4 influences, this many vertices and joints, packed for it.
  const tuned::Kernel* k = tuned::FindKernel("opencl", 4, n, joint_count);
  if (!k) Die("no embedded OpenCL kernel for 4 influences");
  std::printf("variant: %s\ntuned on: %s (%.3f ms, %.1f GB/s on %s)\n", k->variant, k->device_id, k->median_ms,
              k->gbps, k->dataset);
  tuned::PackedInputs inputs;
  if (!tuned::PackMesh(*k, n, 4, positions.data(), nullptr, joints.data(), weights.data(), &inputs, &error))
    Die("PackMesh: " + error);
  const std::vector<float> palette = tuned::PackPalette(*k, matrices.data(), joint_count);
  if (palette.empty()) Die("PackPalette refused the palette");

  // Plain OpenCL on the PoCL device.
  cl_uint platform_count = 0;
  Check(clGetPlatformIDs(0, nullptr, &platform_count), "clGetPlatformIDs");
  std::vector<cl_platform_id> platforms(platform_count);
  Check(clGetPlatformIDs(platform_count, platforms.data(), nullptr), "clGetPlatformIDs");
  cl_device_id device = nullptr;
  for (cl_platform_id p : platforms) {
    char name[256] = {};
    clGetPlatformInfo(p, CL_PLATFORM_NAME, sizeof name, name, nullptr);
    if (std::strstr(name, "Portable Computing Language") && clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 1, &device, nullptr) == CL_SUCCESS) break;
  }
  if (!device) Die("no PoCL device");
  cl_int err = CL_SUCCESS;
  cl_context context = clCreateContext(nullptr, 1, &device, nullptr, nullptr, &err);
  Check(err, "clCreateContext");
  cl_command_queue queue = clCreateCommandQueue(context, device, 0, &err);
  Check(err, "clCreateCommandQueue");
  const char* source = k->source;
  cl_program program = clCreateProgramWithSource(context, 1, &source, nullptr, &err);
  Check(err, "clCreateProgramWithSource");
  if (clBuildProgram(program, 1, &device, "", nullptr, nullptr) != CL_SUCCESS) Die("the embedded kernel did not build");
  cl_kernel kernel = clCreateKernel(program, k->entry_point, &err);
  Check(err, "clCreateKernel");

  const std::size_t out_bytes = n * tuned::OutputStrideBytes(*k);
  std::vector<cl_mem> buffers;
  auto buffer = [&](cl_mem_flags flags, std::size_t bytes, const void* data) {
    buffers.push_back(clCreateBuffer(context, flags | (data ? CL_MEM_COPY_HOST_PTR : 0), bytes, const_cast<void*>(data), &err));
    Check(err, "clCreateBuffer");
    return buffers.back();
  };
  cl_mem out = nullptr;
  const cl_uint count = static_cast<cl_uint>(n), first = 0;
  for (int a = 0; a < k->argument_count; ++a) {  // arguments in the order of the kernel (and its sidecar)
    const tuned::Argument& arg = k->arguments[a];
    const std::string name = arg.name;
    cl_mem mem = nullptr;
    if (name == "n") Check(clSetKernelArg(kernel, a, sizeof count, &count), "clSetKernelArg n");
    else if (name == "first") Check(clSetKernelArg(kernel, a, sizeof first, &first), "clSetKernelArg first");
    else if (name == "out_positions") {
      const std::vector<unsigned char> poison(out_bytes, 0xff);  // NaN: a vertex never written fails the check
      mem = out = buffer(CL_MEM_WRITE_ONLY, out_bytes, poison.data());
    } else if (name == "palette" && arg.image) {
      cl_mem rows = buffer(CL_MEM_READ_ONLY, palette.size() * 4, palette.data());
      const cl_image_format format = {CL_RGBA, CL_FLOAT};
      cl_image_desc desc = {};
      desc.image_type = CL_MEM_OBJECT_IMAGE1D_BUFFER;
      desc.image_width = palette.size() / 4;
      desc.buffer = rows;
      buffers.push_back(mem = clCreateImage(context, CL_MEM_READ_ONLY, &format, &desc, nullptr, &err));
      Check(err, "clCreateImage");
    } else if (name == "palette") mem = buffer(CL_MEM_READ_ONLY, palette.size() * 4, palette.data());
    else {
      const std::vector<std::uint8_t>* data = name == "records" ? &inputs.records : name == "positions" ? &inputs.positions
                                             : name == "indices" ? &inputs.indices : name == "weights" ? &inputs.weights
                                             : name == "normals" ? &inputs.normals : nullptr;
      if (!data || data->empty()) Die("the kernel takes an argument this program does not know: " + name);
      mem = buffer(CL_MEM_READ_ONLY, data->size(), data->data());
    }
    if (mem) Check(clSetKernelArg(kernel, a, sizeof mem, &mem), "clSetKernelArg");
  }
  const std::size_t global = tuned::GlobalWorkItems(*k, n), local = std::size_t(k->wg_size);
  Check(clEnqueueNDRangeKernel(queue, kernel, 1, nullptr, &global, &local, 0, nullptr, nullptr), "clEnqueueNDRangeKernel");
  std::vector<unsigned char> output(out_bytes);
  Check(clEnqueueReadBuffer(queue, out, CL_TRUE, 0, out_bytes, output.data(), 0, nullptr, nullptr), "clEnqueueReadBuffer");
  std::vector<float> skinned(n * 3);
  tuned::UnpackPositions(*k, output.data(), n, skinned.data());

  std::ofstream file(argv[3], std::ios::binary);
  const std::uint32_t header[4] = {0x31565453u /* "STV1" */, count, 0, 0};
  file.write(reinterpret_cast<const char*>(header), sizeof header);
  file.write(reinterpret_cast<const char*>(skinned.data()), std::streamsize(skinned.size() * 4));
  if (!file) Die(std::string("cannot write ") + argv[3]);
  for (cl_mem m : buffers) clReleaseMemObject(m);
  clReleaseKernel(kernel);
  clReleaseProgram(program);
  clReleaseCommandQueue(queue);
  clReleaseContext(context);
  return 0;
}
