// Real servers for the streaming tests, as child processes: nginx through scripts/cells-server
// and tests/fake_range_server.py (faults on demand), plus a temporary folder and a free port.
// Header-only, for tests (IG_SOURCE_DIR comes from ig_add_test).
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace ig::test {

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    char tmpl[] = "/tmp/ig_stream_test.XXXXXX";
    char* p = mkdtemp(tmpl);
    if (!p) std::abort();
    path = p;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

inline int freePort() {
  int s = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  EXPECT_EQ(::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  socklen_t len = sizeof a;
  ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(s);
  return ntohs(a.sin_port);
}

// Runs a shell command, returns its exit status and stdout.
inline int run(const std::string& cmd, std::string& out) {
  out.clear();
  FILE* f = ::popen(cmd.c_str(), "r");
  if (!f) return -1;
  char buf[512];
  while (std::fgets(buf, sizeof buf, f)) out += buf;
  int st = ::pclose(f);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

// nginx through scripts/cells-server, owned by this process: a test that crashes or is killed
// (ctest's timeout) before stop() leaves no server running (the script's watcher stops it).
struct Nginx {
  std::string rundir, url;
  bool running = false;
  Nginx(const std::filesystem::path& dir) : rundir((dir / "run").string()) {}
  ~Nginx() { stop(); }
  void start(const std::filesystem::path& root, int port, uint64_t rate) {
    std::string out;
    std::string cmd = std::string(IG_SOURCE_DIR) + "/scripts/cells-server start --root '" + root.string() +
                      "' --port " + std::to_string(port) + " --rate " + std::to_string(rate) + " --dir '" + rundir +
                      "' --owner " + std::to_string(::getpid()) + " 2>&1";
    int rc = run(cmd, out);
    ASSERT_EQ(rc, 0) << cmd << "\n" << out;
    ASSERT_EQ(out.rfind("http://127.0.0.1:", 0), 0u) << out;
    url = out.substr(0, out.find('\n'));
    running = true;
  }
  void stop() {
    if (!running) return;
    std::string out;
    run(std::string(IG_SOURCE_DIR) + "/scripts/cells-server stop --dir '" + rundir + "' 2>&1", out);
    running = false;
  }
};

// tests/fake_range_server.py as a child process.
struct FakeServer {
  pid_t pid = -1;
  int outFd = -1;
  std::string url;
  explicit FakeServer(std::vector<std::string> args) {
    const char* py = ::access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "python3";
    std::string script = std::string(IG_SOURCE_DIR) + "/tests/fake_range_server.py";
    args.insert(args.begin(), {py, script});
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) std::abort();
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
    int rc = posix_spawnp(&pid, py, &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(fds[1]);
    outFd = fds[0];
    if (rc != 0) {
      pid = -1;
      return;
    }
    // First line: the URL.
    char c;
    while (::read(outFd, &c, 1) == 1 && c != '\n') url += c;
  }
  ~FakeServer() {
    if (pid > 0) {
      ::kill(pid, SIGTERM);
      int st;
      ::waitpid(pid, &st, 0);
    }
    if (outFd >= 0) ::close(outFd);
  }
};

}  // namespace ig::test
