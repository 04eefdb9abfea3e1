#include "rest_cache.hpp"

namespace pinsim::sdf {

void RestCache::store(std::size_t i, const RestRecord* hit, const RestRecord& m) {
  const std::size_t j =
      hit != nullptr ? static_cast<std::size_t>(hit - &records_[i * kSlots]) : next_[i];
  if (hit == nullptr) next_[i] = static_cast<uint8_t>((j + 1) % kSlots);
  records_[i * kSlots + j] = m;
  valid_[i] = static_cast<uint8_t>(valid_[i] | 1u << j);
}

}  // namespace pinsim::sdf
