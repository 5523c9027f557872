#pragma once
// The BLE store: one SQLite file holding data sets with their points and fits with their coefficients,
// covariance, metrics and provenance, so a fit can be reproduced from what is stored.
//
// The schema is versioned with PRAGMA user_version; opening an older file migrates it in a transaction, opening a
// newer one is an error. Fit names are unique; replacing one needs replace = true. Every write is one
// transaction: a failure leaves the file as it was.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "blt/ble/fit.hpp"
#include "blt/ble/impact_data.hpp"

struct sqlite3;

namespace blt::ble {

struct StoredFit {
  std::string name;
  std::string family = "christiansen";
  FitOptions options;               // everything needed to run the fit again
  FitResult result;
  std::vector<ImpactPoint> points;  // the data it was fitted to
  std::string dataOrigin;           // the files (and filters) the points came from
  std::string dataHash;             // hashPoints(points); saveFit computes it (and refuses one that differs)
  std::string toolVersion;          // blt version that made it
  std::string createdUtc;           // ISO 8601, set by saveFit when empty
};

struct FitSummary {
  std::string name, family, method, createdUtc, dataHash;
  int pointCount = 0;
  double meanSquareError = 0;  // m²
  int misclassified = 0;
};

class BleStore {
 public:
  static constexpr int kSchemaVersion = 1;

  // Opens or creates the database file. Throws InputError (naming the file) when it is not a blt BLE store or was
  // written by a newer blt.
  explicit BleStore(const std::string& path);
  ~BleStore();
  BleStore(const BleStore&) = delete;
  BleStore& operator=(const BleStore&) = delete;

  // Saves the fit and its data set in one transaction. Throws InputError when the name exists and !replace, or
  // for a NaN anywhere but the covariance (SQLite would keep it as NULL). Doubles come back bit for bit, except
  // that -0 comes back as +0. Replacing a fit also removes its old data set when no other fit uses it.
  void saveFit(const StoredFit& fit, bool replace);
  // Throws InputError naming the fits present when there is no fit of that name.
  StoredFit loadFit(const std::string& name) const;
  std::vector<FitSummary> listFits() const;
  bool hasFit(const std::string& name) const;
  int schemaVersion() const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

// A stable fingerprint of the points (hex), independent of platform: the same data always hash the same.
std::string hashPoints(const std::vector<ImpactPoint>& points);

// A fit as saveFit wants it: its name, options, result, points and their origin, with the points' hash and this
// blt's version filled in.
StoredFit storedFit(std::string name, const FitOptions& options, FitResult result, std::vector<ImpactPoint> points,
                    std::string dataOrigin);

}  // namespace blt::ble
