// libble is built out in issue 3 (generalized Christiansen BLE, fitting, SQLite store).
namespace blt::ble {}
