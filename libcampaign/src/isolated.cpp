#include "blt/campaign/isolated.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "blt/core/error.hpp"
#include "blt/sim/run_cache.hpp"

namespace blt::campaign {

namespace {

// A file for one of the child's output streams, without a name: the child writes through the descriptor and the
// parent reads through it, so a campaign killed mid-run (SIGKILL, no destructors) leaves nothing in the temporary
// directory. O_TMPFILE makes it nameless from the start; a named file removed at once (where the file system has
// no O_TMPFILE) still left one behind when the kill came between the two calls, as it did once in 20 kill tests
// under load: a campaign starts its next run just after recording one, which is when a watcher kills it.
class CaptureFile {
 public:
  explicit CaptureFile(const char* stream) {
    const std::string dir = std::filesystem::temp_directory_path().string();
    fd_ = open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd_ < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
      std::string pattern = (std::filesystem::path(dir) / ("blt-run-" + std::string(stream) + "-XXXXXX")).string();
      fd_ = mkostemp(pattern.data(), O_CLOEXEC);
      if (fd_ >= 0) unlink(pattern.c_str());
    }
    if (fd_ < 0)
      throw std::runtime_error("cannot make a file in " + dir + " for the run's " + stream + ": " + std::strerror(errno));
  }
  ~CaptureFile() { close(fd_); }
  CaptureFile(const CaptureFile&) = delete;
  CaptureFile& operator=(const CaptureFile&) = delete;
  int fd() const { return fd_; }
  std::string text() const {
    std::string s;
    char buffer[65536];
    for (off_t at = 0;;) {
      const ssize_t n = pread(fd_, buffer, sizeof buffer, at);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      s.append(buffer, static_cast<std::size_t>(n));
      at += n;
    }
    return s;
  }

 private:
  int fd_ = -1;
};

std::string tail(const std::string& text, std::size_t bytes) {
  std::string t = text.size() > bytes ? "..." + text.substr(text.size() - bytes) : text;
  while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.pop_back();
  for (char& c : t)
    if (c == '\n') c = ' ';
  return t;
}

SimulationOutcome runIsolated(const IsolatedRunOptions& o, const sim::ImpactScenario& scenario) {
  if (scenario.path.empty())
    throw std::runtime_error("a run in its own process needs the scenario's file, and this scenario has none");
  std::vector<std::string> args = {o.executable, "sim", "run", scenario.path};
  for (const std::string& s : scenario.settings) {
    args.push_back("--set");
    args.push_back(s);
  }
  for (const char* a : {"--json", "--quiet", "--threads"}) args.emplace_back(a);
  args.push_back(std::to_string(o.threads));
  const bool checkpointing = !o.checkpointDirectory.empty() && o.checkpointSeconds > 0;
  const std::string keep = checkpointing ? checkpointDirectoryFor(o, scenario) : std::string();
  if (checkpointing) {
    char every[32];
    std::snprintf(every, sizeof every, "%.6gs", o.checkpointSeconds);
    for (const std::string& a : {std::string("--out"), keep, std::string("--no-frames"), std::string("--checkpoint-every"),
                                std::string(every)})
      args.push_back(a);
    if (std::filesystem::exists(std::filesystem::path(keep) / (scenario.name + "_checkpoint.bin")))
      args.emplace_back("--resume");
  }
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  const CaptureFile out("stdout"), err("stderr");
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("cannot start a process for the run: ") + std::strerror(errno));
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec: this process has other threads.
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(126);  // the campaign died before prctl took hold
    dup2(out.fd(), STDOUT_FILENO);
    dup2(err.fd(), STDERR_FILENO);
    close_range(3, ~0U, 0);  // the run database and other runs' files stay with the campaign
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw std::runtime_error(std::string("lost the run's process: ") + std::strerror(errno));

  // The run has ended and its outcome is recorded, whatever it was; the checkpoint is only of use to a run whose
  // campaign died with it (nothing recorded), which finds it when the campaign is started again.
  if (checkpointing) {
    std::error_code ignored;
    std::filesystem::remove_all(keep, ignored);
  }
  SimulationOutcome r;
  const std::string errors = tail(err.text(), o.errorTailBytes);
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    r.failed = true;
    r.reason = "the run crashed: signal " + std::to_string(sig) + " (" + strsignal(sig) + ")" +
               (sig == SIGKILL ? ", perhaps killed for memory" : "") + (errors.empty() ? "" : "; it wrote: " + errors);
    return r;
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code != 0) {
    r.failed = true;
    r.reason = (code == 127 ? "cannot run " + o.executable : "blt sim run exited with status " + std::to_string(code)) +
               (errors.empty() ? "" : ": " + errors);
    return r;
  }
  nlohmann::json summary;
  try {
    summary = nlohmann::json::parse(out.text());
  } catch (const std::exception& e) {
    r.failed = true;
    r.reason = std::string("the run's JSON could not be read: ") + e.what();
    return r;
  }
  r.failed = summary.value("status", "") == "unstable";
  if (r.failed) r.reason = "the run went unstable: " + summary.value("message", "");
  r.perforated = summary.value("perforated", false);
  r.settled = summary.value("settled", false);
  r.residualVelocity = summary.value("residual_velocity_m_s", 0.0);
  r.wallSeconds = summary.value("wall_time_s", 0.0);
  r.measurements = std::move(summary);
  return r;
}

}  // namespace

std::string checkpointDirectoryFor(const IsolatedRunOptions& options, const sim::ImpactScenario& scenario) {
  return (std::filesystem::path(options.checkpointDirectory) /
          sim::scenarioHash(scenario.path + "\n" + sim::buildVersion(), scenario.settings))
      .string();
}

Simulator isolatedSimulator(const IsolatedRunOptions& options) {
  if (options.executable.empty() || access(options.executable.c_str(), X_OK) != 0)
    throw InputError(InputLocation::file(options.executable.empty() ? "(none)" : options.executable),
                     "is not an executable blt program, needed to run each simulation in its own process",
                     "the path of the blt program");
  return [options](const sim::ImpactScenario& scenario) { return runIsolated(options, scenario); };
}

Simulator campaignSimulator(bool inProcess, int threads, const std::string& checkpointDirectory,
                            double checkpointSeconds) {
  if (inProcess && checkpointSeconds > 0)
    throw InputError(InputLocation::flag("--checkpoint-every"), "runs in process keep no checkpoints",
                     "runs in their own processes (no --in-process, no --mpi)");
  if (inProcess) return impactSimulator(threads);
  IsolatedRunOptions io;
  io.checkpointDirectory = checkpointDirectory;
  io.checkpointSeconds = checkpointSeconds;
  // The running image itself, not its path: a build that replaces the file mid-campaign does not mix programs.
  io.executable = "/proc/self/exe";
  io.threads = threads;
  return isolatedSimulator(io);
}

}  // namespace blt::campaign
