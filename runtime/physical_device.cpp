#include "runtime/physical_device.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <exception>
#include <fstream>
#include <string>
#include <map>

namespace skintune::internal {

namespace {

// Datasheet figures, for a chip that no API of this machine reports truthfully
// (e.g. only NVIDIA's OpenCL is installed). CUDA's CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE
// reads 52428800 on an H100 (docs/results), 41943040 on an A100.
struct KnownChip {
  const char* name_part;
  std::uint64_t llc_bytes;
};
constexpr std::array<KnownChip, 2> kKnownChips{{
    {"H100", 50ull << 20},  // NVIDIA H100 datasheet: 50 MB L2
    {"A100", 40ull << 20},  // NVIDIA A100 datasheet: 40 MB L2
}};

std::string ChipKey(const CacheReport& d) {
  if (d.type == "cpu") return "host";
  if (!d.uuid.empty()) return "uuid:" + d.uuid;
  if (!d.pci_bus_id.empty()) return "pci:" + d.pci_bus_id;
  return "";  // a chip of its own
}

std::string MatchedBy(const CacheReport& d) {
  if (d.type == "cpu") return "the host";
  if (!d.uuid.empty()) return "UUID " + d.uuid;
  return "PCI " + d.pci_bus_id;
}

bool Credible(std::uint64_t bytes, const CacheReport& d) {
  return bytes > 0 && (d.memory_bytes == 0 || bytes <= d.memory_bytes);
}

}  // namespace

std::uint64_t KnownLastLevelCacheBytes(const std::string& device_name) {
  for (const KnownChip& chip : kKnownChips)
    if (device_name.find(chip.name_part) != std::string::npos) return chip.llc_bytes;
  return 0;
}

std::uint64_t HostLastLevelCacheBytes() {
  std::uint64_t best = 0;
  for (int index = 0; index < 8; ++index) {
    std::ifstream in("/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(index) + "/size");
    std::string text;
    if (!(in >> text) || text.empty()) continue;
    std::uint64_t value = 0;
    std::size_t used = 0;
    try {
      value = std::stoull(text, &used);
    } catch (const std::exception&) {
      continue;
    }
    const char unit = used < text.size() ? text[used] : 'B';
    if (unit == 'K') value <<= 10;
    if (unit == 'M') value <<= 20;
    if (unit == 'G') value <<= 30;
    best = std::max(best, value);
  }
  if (best == 0)  // no sysfs: what the C library knows
    for (int level : {_SC_LEVEL4_CACHE_SIZE, _SC_LEVEL3_CACHE_SIZE, _SC_LEVEL2_CACHE_SIZE}) {
      const long bytes = sysconf(level);
      if (bytes > 0) best = std::max(best, static_cast<std::uint64_t>(bytes));
    }
  return best;
}

std::string UuidHex(const unsigned char* bytes16) {
  std::string hex;
  bool any = false;
  for (int i = 0; i < 16; ++i) {
    char digits[3];
    std::snprintf(digits, sizeof digits, "%02x", bytes16[i]);
    hex += digits;
    any = any || bytes16[i] != 0;
  }
  return any ? hex : "";
}

std::vector<CacheFigure> ResolveLastLevelCaches(const std::vector<CacheReport>& devices,
                                                std::uint64_t host_llc_bytes) {
  // Every figure a device offers for its chip, with where it came from.
  struct Offer {
    CacheFigure figure;
    std::size_t device = 0;  // which device offered it
  };
  auto offers_of = [&](std::size_t i) {
    const CacheReport& d = devices[i];
    std::vector<Offer> offers;
    if (Credible(d.reported_llc, d)) offers.push_back({{d.reported_llc, d.backend + " '" + d.name + "' reports it"}, i});
    if (const std::uint64_t known = KnownLastLevelCacheBytes(d.name))
      offers.push_back({{known, "the datasheet of '" + d.name + "'"}, i});
    if (d.type == "cpu" && host_llc_bytes)
      offers.push_back({{host_llc_bytes, "the host's last-level cache (sysfs)"}, i});
    return offers;
  };
  std::map<std::string, Offer> best;  // per chip
  std::vector<Offer> own(devices.size());
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const std::string chip = ChipKey(devices[i]);
    for (const Offer& o : offers_of(i)) {
      if (o.figure.bytes > own[i].figure.bytes) own[i] = o;
      if (!chip.empty() && o.figure.bytes > best[chip].figure.bytes) best[chip] = o;
    }
  }
  std::vector<CacheFigure> out;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const auto shared = best.find(ChipKey(devices[i]));
    if (shared == best.end() || shared->second.figure.bytes <= own[i].figure.bytes) {
      out.push_back(own[i].figure);
    } else {
      const Offer& o = shared->second;
      out.push_back({o.figure.bytes, o.figure.source + ", the same chip as this " + devices[i].backend + " device (" +
                                         MatchedBy(devices[i]) + ")"});
    }
  }
  return out;
}

}  // namespace skintune::internal
