#pragma once
// The time stamps the stores write (BLE fits, campaign runs): UTC, ISO 8601, to the second.
#include <string>

namespace blt {

std::string nowUtcIso8601();  // "2026-12-01T14:12:03Z"

}  // namespace blt
