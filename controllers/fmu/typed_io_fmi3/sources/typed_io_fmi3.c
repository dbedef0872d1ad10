/*
 * Typed-interface test controller: FMI 3.0 co-simulation FMU (ctmm, controllers/fmu/typed_io_fmi3).
 *
 *     command   (Float32) = enable ? (float)(gain * position) * (invert ? -1 : 1) : 0
 *     count_out (Int32)   = count_in + offset + (number of completed doSteps)
 *     active    (Boolean) = enable
 *     level_out (UInt8)   = level
 *
 * Outputs are computed from the current inputs when read (direct feedthrough).  Testing aid:
 * fmi3DoStep returns fmi3Discard from the communication point "discard_at_time" [s] on.  The
 * arrays "weights" (parameter) and "history" (output) exist only to be refused by ctmm.
 *
 * Build with the definitions of sources/buildDescription.xml (build_fmu reads them).
 */
#ifndef TYPED_IO_FROM_BUILD_DESCRIPTION
#error "compile with the PreprocessorDefinition of sources/buildDescription.xml"
#endif

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define INSTANTIATION_TOKEN "{8d6f3c0e-5b1a-4c4e-9a53-2f7e6b1d0c11}"

enum { VR_TIME = 0, VR_GAIN = 1, VR_DISCARD_AT_TIME = 2, VR_WEIGHTS = 3, VR_OFFSET = 4, VR_INVERT = 5,
       VR_POSITION = 10, VR_COUNT_IN = 11, VR_ENABLE = 12, VR_LEVEL = 13,
       VR_COMMAND = 20, VR_COUNT_OUT = 21, VR_ACTIVE = 22, VR_LEVEL_OUT = 23, VR_HISTORY = 24 };

typedef enum { MODE_INSTANTIATED, MODE_INITIALIZATION, MODE_STEP, MODE_TERMINATED, MODE_ERROR } Mode;

/* Everything fmi3GetFMUState has to copy. */
typedef struct {
    fmi3Float64 time, gain, discard_at_time, weights[3], history[3];
    fmi3Int32 offset, count_in, steps;
    fmi3Boolean invert, enable;
    fmi3Float32 position;
    fmi3UInt8 level;
    Mode mode;
} Data;

typedef struct {
    Data data;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logMessage;
} Instance;

static void set_start_values(Data *d) {
    memset(d, 0, sizeof(*d));
    d->gain = 2.0;
    d->discard_at_time = 1e300;
    d->weights[0] = 1.0;
    d->weights[1] = 2.0;
    d->weights[2] = 3.0;
    d->enable = fmi3True;
    d->mode = MODE_INSTANTIATED;
}

static fmi3Status fail(Instance *inst, fmi3Status status, const char *format, ...) {
    char buffer[512];
    va_list args;
    if (inst != NULL && inst->logMessage != NULL) {
        va_start(args, format);
        vsnprintf(buffer, sizeof(buffer), format, args);
        va_end(args);
        inst->logMessage(inst->environment, status, "logStatusError", buffer);
    }
    return status;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi3.c, a link to
   controllers/fmu_common/unsupported_fmi3.c, compiled beside this file) */
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function);
fmi3Status ctmm_fmi3_not_supported(fmi3Instance instance, const char *function) { return fail((Instance *)instance, fmi3Error, "%s is not supported by this FMU", function); }

static fmi3Float32 command(const Data *d) {
    fmi3Float32 value;
    if (!d->enable) return 0.0f;
    value = (fmi3Float32)(d->gain * (fmi3Float64)d->position);
    return d->invert ? -value : value;
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)loggingOn;
    (void)nCategories;
    (void)categories;
    return instance == NULL ? fmi3Error : fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance tmp, *inst;
    (void)instanceName;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)eventModeUsed;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    memset(&tmp, 0, sizeof(tmp));
    tmp.environment = instanceEnvironment;
    tmp.logMessage = logMessage;
    if (instantiationToken == NULL || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        fail(&tmp, fmi3Error, "wrong instantiation token %s, expected %s",
             instantiationToken != NULL ? instantiationToken : "(null)", INSTANTIATION_TOKEN);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) return NULL;
    *inst = tmp;
    set_start_values(&inst->data);
    return (fmi3Instance)inst;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *inst = (Instance *)instance;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (inst == NULL) return fmi3Error;
    if (inst->data.mode != MODE_INSTANTIATED) return fail(inst, fmi3Error, "fmi3EnterInitializationMode called twice");
    inst->data.time = startTime;
    inst->data.mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (inst == NULL) return fmi3Error;
    if (inst->data.mode != MODE_INITIALIZATION) return fail(inst, fmi3Error, "not in initialization mode");
    inst->data.mode = MODE_STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    ((Instance *)instance)->data.mode = MODE_STEP;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    ((Instance *)instance)->data.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    set_start_values(&((Instance *)instance)->data);
    return fmi3OK;
}

/* ---------------------------------------------------------------- values */

#define CHECK_SCALARS(inst, name)                                                               \
    if ((inst) == NULL) return fmi3Error;                                                       \
    if (nValues != nValueReferences)                                                            \
        return fail(inst, fmi3Error, "%s: all variables of this type are scalars", name);

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k, n = 0;
    if (inst == NULL) return fmi3Error;
    for (k = 0; k < nValueReferences; k++) {
        const Data *d = &inst->data;
        const fmi3Float64 *array = NULL;
        switch (valueReferences[k]) {
        case VR_TIME: if (n < nValues) values[n++] = d->time; break;
        case VR_GAIN: if (n < nValues) values[n++] = d->gain; break;
        case VR_DISCARD_AT_TIME: if (n < nValues) values[n++] = d->discard_at_time; break;
        case VR_WEIGHTS: array = d->weights; break;
        case VR_HISTORY: array = d->history; break;
        default: return fail(inst, fmi3Error, "fmi3GetFloat64: %u is not a Float64 variable", (unsigned)valueReferences[k]);
        }
        if (array != NULL) {
            if (n + 3 > nValues) return fail(inst, fmi3Error, "fmi3GetFloat64: nValues too small for an array");
            memcpy(values + n, array, 3 * sizeof(fmi3Float64));
            n += 3;
        }
    }
    return n == nValues ? fmi3OK : fail(inst, fmi3Error, "fmi3GetFloat64: nValues = %u, expected %u",
                                        (unsigned)nValues, (unsigned)n);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k, n = 0;
    if (inst == NULL) return fmi3Error;
    for (k = 0; k < nValueReferences; k++) {
        Data *d = &inst->data;
        switch (valueReferences[k]) {
        case VR_GAIN: if (n < nValues) d->gain = values[n++]; break;
        case VR_DISCARD_AT_TIME: if (n < nValues) d->discard_at_time = values[n++]; break;
        case VR_WEIGHTS:
            if (n + 3 > nValues) return fail(inst, fmi3Error, "fmi3SetFloat64: nValues too small for an array");
            memcpy(d->weights, values + n, 3 * sizeof(fmi3Float64));
            n += 3;
            break;
        default: return fail(inst, fmi3Error, "fmi3SetFloat64: %u cannot be set", (unsigned)valueReferences[k]);
        }
    }
    return n == nValues ? fmi3OK : fail(inst, fmi3Error, "fmi3SetFloat64: nValues = %u, expected %u",
                                        (unsigned)nValues, (unsigned)n);
}

fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float32 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3GetFloat32")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_POSITION) values[k] = inst->data.position;
        else if (valueReferences[k] == VR_COMMAND) values[k] = command(&inst->data);
        else return fail(inst, fmi3Error, "fmi3GetFloat32: %u is not a Float32 variable", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float32 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3SetFloat32")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_POSITION) return fail(inst, fmi3Error, "fmi3SetFloat32: %u cannot be set",
                                                           (unsigned)valueReferences[k]);
        inst->data.position = values[k];
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3GetInt32")
    for (k = 0; k < nValueReferences; k++) {
        const Data *d = &inst->data;
        if (valueReferences[k] == VR_OFFSET) values[k] = d->offset;
        else if (valueReferences[k] == VR_COUNT_IN) values[k] = d->count_in;
        else if (valueReferences[k] == VR_COUNT_OUT) values[k] = d->count_in + d->offset + d->steps;
        else return fail(inst, fmi3Error, "fmi3GetInt32: %u is not an Int32 variable", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3SetInt32")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_OFFSET) inst->data.offset = values[k];
        else if (valueReferences[k] == VR_COUNT_IN) inst->data.count_in = values[k];
        else return fail(inst, fmi3Error, "fmi3SetInt32: %u cannot be set", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3UInt8 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3GetUInt8")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_LEVEL || valueReferences[k] == VR_LEVEL_OUT) values[k] = inst->data.level;
        else return fail(inst, fmi3Error, "fmi3GetUInt8: %u is not a UInt8 variable", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3UInt8 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3SetUInt8")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] != VR_LEVEL) return fail(inst, fmi3Error, "fmi3SetUInt8: %u cannot be set",
                                                        (unsigned)valueReferences[k]);
        inst->data.level = values[k];
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Boolean values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3GetBoolean")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_INVERT) values[k] = inst->data.invert;
        else if (valueReferences[k] == VR_ENABLE || valueReferences[k] == VR_ACTIVE) values[k] = inst->data.enable;
        else return fail(inst, fmi3Error, "fmi3GetBoolean: %u is not a Boolean variable", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Boolean values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t k;
    CHECK_SCALARS(inst, "fmi3SetBoolean")
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_INVERT) inst->data.invert = values[k];
        else if (valueReferences[k] == VR_ENABLE) inst->data.enable = values[k];
        else return fail(inst, fmi3Error, "fmi3SetBoolean: %u cannot be set", (unsigned)valueReferences[k]);
    }
    return fmi3OK;
}

/* ---------------------------------------------------------------- FMU state and stepping */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *inst = (Instance *)instance;
    Data *copy;
    if (inst == NULL || FMUState == NULL) return fmi3Error;
    copy = (Data *)*FMUState;
    if (copy == NULL) {
        copy = (Data *)calloc(1, sizeof(Data));
        if (copy == NULL) return fmi3Error;
    }
    *copy = inst->data;
    *FMUState = (fmi3FMUState)copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    ((Instance *)instance)->data = *(const Data *)FMUState;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *inst = (Instance *)instance;
    Data *d;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL) return fmi3Error;
    d = &inst->data;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = d->time;
    if (d->mode != MODE_STEP) return fail(inst, fmi3Error, "fmi3DoStep called outside step mode");
    if (!(communicationStepSize > 0.0)) return fail(inst, fmi3Error, "fmi3DoStep: step size %g is not > 0",
                                                     communicationStepSize);
    if (currentCommunicationPoint >= d->discard_at_time)
        return fail(inst, fmi3Discard, "fmi3DoStep at t = %.17g: discarded (discard_at_time = %.17g)",
                    currentCommunicationPoint, d->discard_at_time);
    d->history[2] = d->history[1];
    d->history[1] = d->history[0];
    d->history[0] = d->position;
    d->steps += 1;
    d->time = currentCommunicationPoint + communicationStepSize;
    *lastSuccessfulTime = d->time;
    return fmi3OK;
}
