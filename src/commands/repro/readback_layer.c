/*
 * VK_LAYER_TRILAB_readback: a small Vulkan layer that keeps what a replay read back.
 *
 * `trilab repro --check DIR --gfxrecon` runs `gfxrecon-replay capture.gfxr` with this layer
 * enabled (VK_LAYER_PATH, VK_INSTANCE_LAYERS), between gfxrecon-replay and the driver. The capture
 * reads the hits back through a host-visible buffer created with usage TRANSFER_DST alone and the
 * hits' size; gfxrecon-replay replays that copy but keeps nothing of it. When such a buffer is
 * destroyed, this layer writes its contents, through the replay's own mapping of its memory, to
 * TRILAB_READBACK_FILE (once). trilab then compares them with the expected hits ray by ray.
 *
 *   TRILAB_READBACK_FILE    where to write the bytes
 *   TRILAB_READBACK_BYTES   the buffer's size (rays x 16)
 *   TRILAB_READBACK_USAGE   its VkBufferUsageFlags (2: TRANSFER_DST)
 *
 * Built by build.rs into the trilab executable (written out when needed). One instance and one
 * device at a time, as a capture of one dispatch has; every call not listed below goes straight
 * to the next layer or the driver.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <vulkan/vk_layer.h>
#include <vulkan/vulkan.h>

#define EXPORT __attribute__((visibility("default")))
#define MAX_OBJECTS 8192

struct tracked_buffer {
    VkBuffer buffer;
    VkDeviceSize size;
    VkBufferUsageFlags usage;
    VkDeviceMemory memory;
    VkDeviceSize offset;
};

struct tracked_memory {
    VkDeviceMemory memory;
    char *mapped;
    VkDeviceSize offset;
};

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static struct tracked_buffer buffers[MAX_OBJECTS];
static int nbuffers;
static struct tracked_memory memories[MAX_OBJECTS];
static int nmemories;
static int written;

static PFN_vkGetInstanceProcAddr next_gipa;
static PFN_vkGetDeviceProcAddr next_gdpa;
static PFN_vkCreateBuffer next_create_buffer;
static PFN_vkDestroyBuffer next_destroy_buffer;
static PFN_vkBindBufferMemory next_bind_buffer_memory;
static PFN_vkBindBufferMemory2 next_bind_buffer_memory2;
static PFN_vkMapMemory next_map_memory;
static PFN_vkUnmapMemory next_unmap_memory;
static PFN_vkFreeMemory next_free_memory;
static PFN_vkInvalidateMappedMemoryRanges next_invalidate;

static struct tracked_buffer *find_buffer(VkBuffer b) {
    for (int i = 0; i < nbuffers; i++)
        if (buffers[i].buffer == b) return &buffers[i];
    return NULL;
}

static struct tracked_memory *find_memory(VkDeviceMemory m) {
    for (int i = 0; i < nmemories; i++)
        if (memories[i].memory == m) return &memories[i];
    return NULL;
}

static void forget_memory(VkDeviceMemory m) {
    struct tracked_memory *t = find_memory(m);
    if (t) *t = memories[--nmemories];
}

static unsigned long long env_number(const char *name) {
    const char *v = getenv(name);
    return v ? strtoull(v, NULL, 10) : 0;
}

/* Writes `b`'s bytes when it is the read-back buffer asked for and its memory is mapped. */
static void keep_if_wanted(VkDevice device, const struct tracked_buffer *b) {
    const char *path = getenv("TRILAB_READBACK_FILE");
    if (written || !path || b->size != env_number("TRILAB_READBACK_BYTES") ||
        b->usage != (VkBufferUsageFlags)env_number("TRILAB_READBACK_USAGE"))
        return;
    struct tracked_memory *m = find_memory(b->memory);
    if (!m || !m->mapped || b->offset < m->offset) return;
    VkMappedMemoryRange range = {VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE, NULL, m->memory, m->offset, VK_WHOLE_SIZE};
    next_invalidate(device, 1, &range);
    FILE *f = fopen(path, "wb");
    if (!f) return;
    size_t n = fwrite(m->mapped + (b->offset - m->offset), 1, (size_t)b->size, f);
    if (fclose(f) == 0 && n == (size_t)b->size) written = 1;
}

static VkResult VKAPI_CALL CreateBuffer(VkDevice device, const VkBufferCreateInfo *info,
                                        const VkAllocationCallbacks *alloc, VkBuffer *buffer) {
    VkResult r = next_create_buffer(device, info, alloc, buffer);
    pthread_mutex_lock(&lock);
    if (r == VK_SUCCESS && nbuffers < MAX_OBJECTS)
        buffers[nbuffers++] = (struct tracked_buffer){*buffer, info->size, info->usage, VK_NULL_HANDLE, 0};
    pthread_mutex_unlock(&lock);
    return r;
}

static void VKAPI_CALL DestroyBuffer(VkDevice device, VkBuffer buffer, const VkAllocationCallbacks *alloc) {
    pthread_mutex_lock(&lock);
    struct tracked_buffer *b = find_buffer(buffer);
    if (b) {
        keep_if_wanted(device, b);
        *b = buffers[--nbuffers];
    }
    pthread_mutex_unlock(&lock);
    next_destroy_buffer(device, buffer, alloc);
}

static void bound(VkBuffer buffer, VkDeviceMemory memory, VkDeviceSize offset) {
    struct tracked_buffer *b = find_buffer(buffer);
    if (b) {
        b->memory = memory;
        b->offset = offset;
    }
}

static VkResult VKAPI_CALL BindBufferMemory(VkDevice device, VkBuffer buffer, VkDeviceMemory memory,
                                            VkDeviceSize offset) {
    VkResult r = next_bind_buffer_memory(device, buffer, memory, offset);
    pthread_mutex_lock(&lock);
    if (r == VK_SUCCESS) bound(buffer, memory, offset);
    pthread_mutex_unlock(&lock);
    return r;
}

static VkResult VKAPI_CALL BindBufferMemory2(VkDevice device, uint32_t count, const VkBindBufferMemoryInfo *infos) {
    VkResult r = next_bind_buffer_memory2(device, count, infos);
    pthread_mutex_lock(&lock);
    for (uint32_t i = 0; r == VK_SUCCESS && i < count; i++) bound(infos[i].buffer, infos[i].memory, infos[i].memoryOffset);
    pthread_mutex_unlock(&lock);
    return r;
}

static VkResult VKAPI_CALL MapMemory(VkDevice device, VkDeviceMemory memory, VkDeviceSize offset, VkDeviceSize size,
                                     VkMemoryMapFlags flags, void **data) {
    VkResult r = next_map_memory(device, memory, offset, size, flags, data);
    pthread_mutex_lock(&lock);
    if (r == VK_SUCCESS) {
        forget_memory(memory);
        if (nmemories < MAX_OBJECTS) memories[nmemories++] = (struct tracked_memory){memory, (char *)*data, offset};
    }
    pthread_mutex_unlock(&lock);
    return r;
}

static void VKAPI_CALL UnmapMemory(VkDevice device, VkDeviceMemory memory) {
    pthread_mutex_lock(&lock);
    forget_memory(memory);
    pthread_mutex_unlock(&lock);
    next_unmap_memory(device, memory);
}

static void VKAPI_CALL FreeMemory(VkDevice device, VkDeviceMemory memory, const VkAllocationCallbacks *alloc) {
    pthread_mutex_lock(&lock);
    forget_memory(memory);
    pthread_mutex_unlock(&lock);
    next_free_memory(device, memory, alloc);
}

static PFN_vkVoidFunction VKAPI_CALL GetDeviceProcAddr(VkDevice device, const char *name);

static VkResult VKAPI_CALL CreateDevice(VkPhysicalDevice physical, const VkDeviceCreateInfo *info,
                                        const VkAllocationCallbacks *alloc, VkDevice *device) {
    VkLayerDeviceCreateInfo *chain = (VkLayerDeviceCreateInfo *)info->pNext;
    while (chain && !(chain->sType == VK_STRUCTURE_TYPE_LOADER_DEVICE_CREATE_INFO && chain->function == VK_LAYER_LINK_INFO))
        chain = (VkLayerDeviceCreateInfo *)chain->pNext;
    if (!chain) return VK_ERROR_INITIALIZATION_FAILED;
    PFN_vkGetInstanceProcAddr gipa = chain->u.pLayerInfo->pfnNextGetInstanceProcAddr;
    next_gdpa = chain->u.pLayerInfo->pfnNextGetDeviceProcAddr;
    chain->u.pLayerInfo = chain->u.pLayerInfo->pNext;
    PFN_vkCreateDevice create = (PFN_vkCreateDevice)gipa(VK_NULL_HANDLE, "vkCreateDevice");
    VkResult r = create(physical, info, alloc, device);
    if (r != VK_SUCCESS) return r;
#define NEXT(type, var, fn) var = (type)next_gdpa(*device, fn)
    NEXT(PFN_vkCreateBuffer, next_create_buffer, "vkCreateBuffer");
    NEXT(PFN_vkDestroyBuffer, next_destroy_buffer, "vkDestroyBuffer");
    NEXT(PFN_vkBindBufferMemory, next_bind_buffer_memory, "vkBindBufferMemory");
    NEXT(PFN_vkBindBufferMemory2, next_bind_buffer_memory2, "vkBindBufferMemory2");
    NEXT(PFN_vkMapMemory, next_map_memory, "vkMapMemory");
    NEXT(PFN_vkUnmapMemory, next_unmap_memory, "vkUnmapMemory");
    NEXT(PFN_vkFreeMemory, next_free_memory, "vkFreeMemory");
    NEXT(PFN_vkInvalidateMappedMemoryRanges, next_invalidate, "vkInvalidateMappedMemoryRanges");
#undef NEXT
    return VK_SUCCESS;
}

static VkResult VKAPI_CALL CreateInstance(const VkInstanceCreateInfo *info, const VkAllocationCallbacks *alloc,
                                          VkInstance *instance) {
    VkLayerInstanceCreateInfo *chain = (VkLayerInstanceCreateInfo *)info->pNext;
    while (chain &&
           !(chain->sType == VK_STRUCTURE_TYPE_LOADER_INSTANCE_CREATE_INFO && chain->function == VK_LAYER_LINK_INFO))
        chain = (VkLayerInstanceCreateInfo *)chain->pNext;
    if (!chain) return VK_ERROR_INITIALIZATION_FAILED;
    next_gipa = chain->u.pLayerInfo->pfnNextGetInstanceProcAddr;
    chain->u.pLayerInfo = chain->u.pLayerInfo->pNext;
    PFN_vkCreateInstance create = (PFN_vkCreateInstance)next_gipa(VK_NULL_HANDLE, "vkCreateInstance");
    return create(info, alloc, instance);
}

static PFN_vkVoidFunction own(const char *name) {
#define OWN(fn)                          \
    if (strcmp(name, "vk" #fn) == 0) \
        return (PFN_vkVoidFunction)fn;
    OWN(CreateBuffer)
    OWN(DestroyBuffer)
    OWN(BindBufferMemory)
    OWN(BindBufferMemory2)
    OWN(MapMemory)
    OWN(UnmapMemory)
    OWN(FreeMemory)
    OWN(GetDeviceProcAddr)
#undef OWN
    return NULL;
}

static PFN_vkVoidFunction VKAPI_CALL GetDeviceProcAddr(VkDevice device, const char *name) {
    PFN_vkVoidFunction f = own(name);
    return f ? f : next_gdpa(device, name);
}

static PFN_vkVoidFunction VKAPI_CALL GetInstanceProcAddr(VkInstance instance, const char *name) {
    if (strcmp(name, "vkCreateInstance") == 0) return (PFN_vkVoidFunction)CreateInstance;
    if (strcmp(name, "vkCreateDevice") == 0) return (PFN_vkVoidFunction)CreateDevice;
    if (strcmp(name, "vkGetInstanceProcAddr") == 0) return (PFN_vkVoidFunction)GetInstanceProcAddr;
    PFN_vkVoidFunction f = own(name);
    if (f) return f;
    return next_gipa ? next_gipa(instance, name) : NULL;
}

EXPORT VkResult VKAPI_CALL vkNegotiateLoaderLayerInterfaceVersion(VkNegotiateLayerInterface *v) {
    if (v->loaderLayerInterfaceVersion > 2) v->loaderLayerInterfaceVersion = 2;
    v->pfnGetInstanceProcAddr = GetInstanceProcAddr;
    v->pfnGetDeviceProcAddr = GetDeviceProcAddr;
    v->pfnGetPhysicalDeviceProcAddr = NULL;
    return VK_SUCCESS;
}
