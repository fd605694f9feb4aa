/* LD_PRELOAD shim for Debian's user-mode Linux 6.1 (linux.uml) on hosts with a large XSAVE area.
 *
 * UML 6.1 saves and restores a guest process's FPU state with PTRACE_GETREGSET /
 * PTRACE_SETREGSET (NT_X86_XSTATE) into a fixed 832-byte buffer. The host kernel accepts a
 * short buffer for GET but refuses SET unless the buffer is the host's whole XSAVE size
 * ("userspace - ptrace set fp regs failed, errno = 14" and a panic when init first runs). On a
 * CPU with AVX-512 and AMX the host size is ~11 KiB, so the guest cannot start at all. Newer
 * kernels size the buffer from the host; this shim does the same from outside: it keeps a full
 * host-sized copy per UML buffer, hands UML the head it asked for, and on SET lays UML's head
 * over the full copy it got last time for that buffer, so no register state is lost.
 *
 * Build: cc -O2 -shared -fPIC -o uml_xstate_shim.so uml_xstate_shim.c
 * Use:   LD_PRELOAD=.../uml_xstate_shim.so linux.uml ...   (scripts/kernel-can.sh does both)
 */
#define _GNU_SOURCE
#include <errno.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/ptrace.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

#define NT_XSTATE 0x202
#define SLOTS 8192
#define PROBE_SIZE (64 * 1024)

struct slot {
    const void *key;
    unsigned char *full;
};

static struct slot table[SLOTS];
static size_t full_size; /* the host's XSAVE regset size, found on first use */

static long raw_ptrace(long req, pid_t pid, void *addr, void *data)
{
    return syscall(SYS_ptrace, req, pid, addr, data);
}

static unsigned char *blob_for(const void *key, int create)
{
    size_t h = ((uintptr_t)key >> 4) % SLOTS;
    for (size_t i = 0; i < SLOTS; i++) {
        struct slot *s = &table[(h + i) % SLOTS];
        if (s->key == key) {
            return s->full;
        }
        if (s->key == NULL) {
            if (!create) {
                return NULL;
            }
            void *mem = mmap(NULL, full_size, PROT_READ | PROT_WRITE,
                             MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
            if (mem == MAP_FAILED) {
                return NULL;
            }
            s->key = key;
            s->full = mem;
            return s->full;
        }
    }
    return NULL;
}

/* The full host state of pid into buf (full_size bytes); finds full_size on first call. */
static long get_full(pid_t pid, unsigned char *buf)
{
    struct iovec iov = {buf, full_size};
    return raw_ptrace(PTRACE_GETREGSET, pid, (void *)NT_XSTATE, &iov);
}

static int probe_size(pid_t pid)
{
    if (full_size != 0) {
        return 0;
    }
    void *mem = mmap(NULL, PROBE_SIZE, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS,
                     -1, 0);
    if (mem == MAP_FAILED) {
        return -1;
    }
    struct iovec iov = {mem, PROBE_SIZE};
    long rc = raw_ptrace(PTRACE_GETREGSET, pid, (void *)NT_XSTATE, &iov);
    munmap(mem, PROBE_SIZE);
    if (rc != 0) {
        return -1;
    }
    full_size = iov.iov_len;
    return 0;
}

static long xstate_get(pid_t pid, struct iovec *iov)
{
    if (probe_size(pid) != 0 || iov->iov_len >= full_size) {
        return raw_ptrace(PTRACE_GETREGSET, pid, (void *)NT_XSTATE, iov);
    }
    unsigned char *full = blob_for(iov->iov_base, 1);
    if (full == NULL) {
        return raw_ptrace(PTRACE_GETREGSET, pid, (void *)NT_XSTATE, iov);
    }
    long rc = get_full(pid, full);
    if (rc != 0) {
        return rc;
    }
    memcpy(iov->iov_base, full, iov->iov_len);
    return 0;
}

static long xstate_set(pid_t pid, struct iovec *iov)
{
    if (probe_size(pid) != 0 || iov->iov_len >= full_size) {
        return raw_ptrace(PTRACE_SETREGSET, pid, (void *)NT_XSTATE, iov);
    }
    unsigned char *full = blob_for(iov->iov_base, 0);
    if (full == NULL) {
        full = blob_for(iov->iov_base, 1);
        if (full == NULL) {
            errno = ENOMEM;
            return -1;
        }
        long rc = get_full(pid, full);
        if (rc != 0) {
            return rc;
        }
    }
    memcpy(full, iov->iov_base, iov->iov_len);
    struct iovec whole = {full, full_size};
    return raw_ptrace(PTRACE_SETREGSET, pid, (void *)NT_XSTATE, &whole);
}

long ptrace(enum __ptrace_request request, ...)
{
    va_list ap;
    va_start(ap, request);
    pid_t pid = va_arg(ap, pid_t);
    void *addr = va_arg(ap, void *);
    void *data = va_arg(ap, void *);
    va_end(ap);
    long req = (long)request;
    if (req == PTRACE_PEEKTEXT || req == PTRACE_PEEKDATA || req == PTRACE_PEEKUSER) {
        long word = 0;
        long rc = raw_ptrace(req, pid, addr, &word);
        if (rc != 0) {
            return -1;
        }
        errno = 0;
        return word;
    }
    if ((req == PTRACE_GETREGSET || req == PTRACE_SETREGSET) &&
        (uintptr_t)addr == NT_XSTATE && data != NULL) {
        return req == PTRACE_GETREGSET ? xstate_get(pid, data) : xstate_set(pid, data);
    }
    return raw_ptrace(req, pid, addr, data);
}
