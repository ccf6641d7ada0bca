// A stand-in for NVML (libnvidia-ml) for the device clock's tests
// (device_clock_test.cpp): the functions skintune loads, answering for one
// GPU, UUID GPU-01234567-89ab-cdef-0123-456789abcdef or PCI bus id
// 0000:41:00.0, whose SM clock is SKINTUNE_FAKE_NVML_MHZ (read at each call;
// unset: 1980) and whose boost clock is 1980 MHz. nvmlInit_v2 fails (999)
// when SKINTUNE_FAKE_NVML_INIT_FAILS is set.
#include <cstdlib>
#include <cstring>

namespace {
int kGpu = 0;  // the one device's handle points here
}  // namespace

extern "C" {

__attribute__((visibility("default"))) int nvmlInit_v2() {
  return std::getenv("SKINTUNE_FAKE_NVML_INIT_FAILS") ? 999 : 0;
}

__attribute__((visibility("default"))) int nvmlDeviceGetHandleByUUID(const char* uuid, void** device) {
  if (std::strcmp(uuid, "GPU-01234567-89ab-cdef-0123-456789abcdef") != 0) return 13;  // NVML_ERROR_NOT_FOUND
  *device = &kGpu;
  return 0;
}

__attribute__((visibility("default"))) int nvmlDeviceGetHandleByPciBusId_v2(const char* pci, void** device) {
  if (std::strcmp(pci, "0000:41:00.0") != 0) return 13;
  *device = &kGpu;
  return 0;
}

__attribute__((visibility("default"))) int nvmlDeviceGetClockInfo(void* device, int type, unsigned* mhz) {
  if (device != &kGpu || type != 1) return 2;  // NVML_ERROR_INVALID_ARGUMENT
  const char* forced = std::getenv("SKINTUNE_FAKE_NVML_MHZ");
  *mhz = forced ? static_cast<unsigned>(std::atoi(forced)) : 1980u;
  return 0;
}

__attribute__((visibility("default"))) int nvmlDeviceGetMaxClockInfo(void* device, int type, unsigned* mhz) {
  if (device != &kGpu || type != 1) return 2;
  *mhz = 1980;
  return 0;
}

}  // extern "C"
