/*
 * FMI 3.0 entry points that controllers/fmu/typed_io_fmi3 does not provide (ctmm): the variable types
 * it does not have, binaries, model-exchange and scheduled-execution instantiation.  The calls no ctmm
 * FMU supports are in the shared unsupported_fmi3.c (a link to controllers/fmu_common).
 *
 * The standard requires every function to be exported; these report fmi3Error (or return NULL for
 * the model-exchange and scheduled-execution instantiation).  Compiled together with
 * typed_io_fmi3.c and unsupported_fmi3.c as listed in sources/buildDescription.xml.
 */
#include <stddef.h>

#include "fmi3Functions.h"


#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

#define GET_SET(name, type, constness)                                                                    \
    fmi3Status name(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    constness type values[], size_t nValues) {                                             \
        if (nValueReferences == 0) return fmi3OK;                                                          \
        return fmi3Error;                                                                                  \
    }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    return NULL; /* co-simulation only */
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    return NULL; /* co-simulation only */
}

GET_SET(fmi3GetInt8, fmi3Int8, )
GET_SET(fmi3GetInt16, fmi3Int16, )
GET_SET(fmi3GetUInt16, fmi3UInt16, )
GET_SET(fmi3GetUInt32, fmi3UInt32, )
GET_SET(fmi3GetInt64, fmi3Int64, )
GET_SET(fmi3GetUInt64, fmi3UInt64, )
GET_SET(fmi3GetString, fmi3String, )
GET_SET(fmi3SetInt8, fmi3Int8, const)
GET_SET(fmi3SetInt16, fmi3Int16, const)
GET_SET(fmi3SetUInt16, fmi3UInt16, const)
GET_SET(fmi3SetUInt32, fmi3UInt32, const)
GET_SET(fmi3SetInt64, fmi3Int64, const)
GET_SET(fmi3SetUInt64, fmi3UInt64, const)
GET_SET(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    if (nValueReferences == 0) return fmi3OK;
    return fmi3Error;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    if (nValueReferences == 0) return fmi3OK;
    return fmi3Error;
}

