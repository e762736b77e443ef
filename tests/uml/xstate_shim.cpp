// LD_PRELOAD shim for Debian 12's user-mode Linux kernel (6.1) on hosts whose XSAVE area is
// larger than the kernel was built for (CPUs with AVX-512 or AMX).
//
// UML saves and restores its processes' FPU state with PTRACE_GETREGSET / PTRACE_SETREGSET
// (NT_X86_XSTATE) in a buffer the size of its own XSAVE layout (x87, SSE, AVX: 832 bytes).
// Current host kernels accept PTRACE_SETREGSET only with a buffer of the host's full XSAVE size,
// so on such CPUs UML's first restore fails ("userspace - ptrace set fp regs failed, errno =
// 14") and it panics before init. Here those two requests go to the host with a full-size
// buffer: a get copies UML's part out of it; a set reads the process's full state first and
// writes it back with UML's part in place, so the components UML does not know (AVX-512, AMX)
// keep what the process had. The guest's glibc is told not to use AVX-512 (tests/uml/init.sh),
// so that no state UML cannot switch between the threads of one process is in use.
// Every other ptrace request passes through unchanged.
#include <dlfcn.h>
#include <elf.h>
#include <sys/ptrace.h>
#include <sys/types.h>
#include <sys/uio.h>

#include <cerrno>
#include <cstdarg>
#include <cstring>

namespace {

using PtraceFn = long (*)(int, pid_t, void*, void*);

PtraceFn realPtrace() {
  static PtraceFn fn = reinterpret_cast<PtraceFn>(dlsym(RTLD_NEXT, "ptrace"));
  return fn;
}

// Larger than any XSAVE area (AMX's is about 11 KB). UML issues its ptrace calls from one
// thread, but a lock-free per-thread buffer costs nothing.
alignas(64) thread_local unsigned char full[65536];

}  // namespace

extern "C" long ptrace(enum __ptrace_request request, ...) {
  va_list ap;
  va_start(ap, request);
  const pid_t pid = va_arg(ap, pid_t);
  void* addr = va_arg(ap, void*);
  void* data = va_arg(ap, void*);
  va_end(ap);
  const PtraceFn real = realPtrace();
  if (!real) {
    errno = ENOSYS;
    return -1;
  }
  const bool xstate = reinterpret_cast<unsigned long>(addr) == NT_X86_XSTATE;
  if (!xstate || (request != PTRACE_GETREGSET && request != PTRACE_SETREGSET) || !data)
    return real(request, pid, addr, data);
  iovec* mine = static_cast<iovec*>(data);
  iovec whole{full, sizeof full};
  const long got = real(PTRACE_GETREGSET, pid, addr, &whole);  // iov_len: the host's size
  if (got < 0 || whole.iov_len <= mine->iov_len) return real(request, pid, addr, data);
  if (request == PTRACE_GETREGSET) {
    std::memcpy(mine->iov_base, full, mine->iov_len);
    return got;
  }
  std::memcpy(full, mine->iov_base, mine->iov_len);
  return real(PTRACE_SETREGSET, pid, addr, &whole);
}
