/* Counts the heap allocations of a process, for the cost guard
 * (tests/test_cost.py, harness/cost.py): preloaded (LD_PRELOAD), it counts
 * every malloc, calloc, realloc and aligned allocation (operator new calls
 * malloc) in a 64-bit counter mapped from the file that YBGC_ALLOC_COUNTS
 * names, which another process reads while this one runs. Built by the
 * harness with the system's C compiler; glibc only (__libc_malloc). */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

extern void* __libc_malloc(size_t size);
extern void* __libc_calloc(size_t count, size_t size);
extern void* __libc_realloc(void* old, size_t size);
extern void* __libc_memalign(size_t alignment, size_t size);

static uint64_t before_start;
static uint64_t* counter = &before_start;

__attribute__((constructor)) static void map_counter(void)
{
    const char* path = getenv("YBGC_ALLOC_COUNTS");
    if (path == NULL) {
        return;
    }
    int fd = open(path, O_RDWR | O_CREAT, 0644);
    if (fd < 0) {
        return;
    }
    if (ftruncate(fd, sizeof(uint64_t)) == 0) {
        void* p = mmap(NULL, sizeof(uint64_t), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
        if (p != MAP_FAILED) {
            counter = (uint64_t*)p;
        }
    }
    close(fd);
}

static inline void count(void)
{
    __atomic_add_fetch(counter, 1, __ATOMIC_RELAXED);
}

void* malloc(size_t size)
{
    count();
    return __libc_malloc(size);
}

void* calloc(size_t n, size_t size)
{
    count();
    return __libc_calloc(n, size);
}

void* realloc(void* old, size_t size)
{
    count();
    return __libc_realloc(old, size);
}

void* memalign(size_t alignment, size_t size)
{
    count();
    return __libc_memalign(alignment, size);
}

void* aligned_alloc(size_t alignment, size_t size)
{
    count();
    return __libc_memalign(alignment, size);
}

int posix_memalign(void** out, size_t alignment, size_t size)
{
    count();
    void* p = __libc_memalign(alignment, size);
    if (p == NULL) {
        return ENOMEM;
    }
    *out = p;
    return 0;
}
