"""The FMI 2.0 co-simulation functions of an exported plant FMU (C text; :mod:`ctmm.fmu_export_runtime`).

:data:`FMI2_INTERFACE` wraps the shared core of :data:`ctmm.fmu_export_runtime.CORE` (instance data,
value references, initialisation, the communication step) in the FMI 2.0 functions: Real variables,
FMU state get/set, ``fmi2DoStep``, ``fmi2GetRealStatus(fmi2LastSuccessfulTime)``.  Integer, Boolean
and String access with values, serialisation, directional and input/output derivatives and
``fmi2CancelStep`` return ``fmi2Error`` (an empty get or set is fine); all but the variable access are the
stubs shared with the shipped controller FMUs (``controllers/fmu_common/unsupported_fmi2.c``, copied beside
this source by :func:`ctmm.fmu_export_files.write_sources`), logging through ``ctmm_fmi2_not_supported``.  The FMU allocates with
``calloc``/``free`` (``canNotUseMemoryManagementFunctions="true"``).
"""
from __future__ import annotations

__all__ = ["FMI2_INTERFACE"]

FMI2_INTERFACE = r"""
/* ================================================================ FMI 2.0 co-simulation */

typedef struct {
    Core *core;
    char *instanceName;
    fmi2CallbackFunctions cb;
    fmi2Boolean loggingOn;
} Instance;

static void interface_log(void *owner, int error, const char *text) {
    Instance *inst = (Instance *)owner;
    if (inst == NULL || inst->cb.logger == NULL || (!error && !inst->loggingOn)) return;
    inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, error ? fmi2Error : fmi2OK,
                    error ? "logStatusError" : "logAll", "%s", text);
}

static fmi2Status not_supported(fmi2Component c, const char *function) {
    report(c, 1, "%s is not supported by this FMU", function);
    return fmi2Error;
}

/* the logger of the shared stubs of unsupported calls (unsupported_fmi2.c, compiled beside this file) */
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function);
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function) { return not_supported(c, function); }

#define CORE_OF(c) (((Instance *)(c))->core)
#define STATUS(failed) ((failed) ? fmi2Error : fmi2OK)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    ((Instance *)c)->loggingOn = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance tmp, *inst;
    const char *name = instanceName != NULL ? instanceName : MODEL_IDENTIFIER;
    (void)fmuResourceLocation;
    (void)visible;
    memset(&tmp, 0, sizeof(tmp));
    if (functions != NULL) tmp.cb = *functions;
    tmp.instanceName = (char *)name;
    tmp.loggingOn = loggingOn;
    if (fmuType != fmi2CoSimulation) {
        report(&tmp, 1, "%s supports co-simulation only", MODEL_IDENTIFIER);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_TOKEN) != 0) {
        report(&tmp, 1, "wrong GUID %s, expected %s", fmuGUID != NULL ? fmuGUID : "(null)", MODEL_TOKEN);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst != NULL) {
        *inst = tmp;
        inst->instanceName = (char *)calloc(strlen(name) + 1, 1);
        inst->core = core_new();
    }
    if (inst == NULL || inst->instanceName == NULL || inst->core == NULL) {
        report(&tmp, 1, "fmi2Instantiate: out of memory");
        if (inst != NULL) {
            free(inst->instanceName);
            core_free(inst->core);
            free(inst);
        }
        return NULL;
    }
    memcpy(inst->instanceName, name, strlen(name) + 1);
    return (fmi2Component)inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) return;
    core_free(inst->core);
    free(inst->instanceName);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL) return fmi2Error;
    if (CORE_OF(c)->data.mode != MODE_INSTANTIATED || !isfinite(startTime)) {
        report(c, 1, "fmi2SetupExperiment: called after initialization or startTime %g not finite", startTime);
        return fmi2Error;
    }
    CORE_OF(c)->data.start_time = startTime;
    CORE_OF(c)->data.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    if (CORE_OF(c)->data.mode != MODE_INSTANTIATED) {
        report(c, 1, "fmi2EnterInitializationMode called twice");
        return fmi2Error;
    }
    CORE_OF(c)->data.mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return STATUS(core_exit_initialization(CORE_OF(c), c));
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    CORE_OF(c)->data.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    core_reset(CORE_OF(c));
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    if (c == NULL) return fmi2Error;
    return STATUS(core_get(CORE_OF(c), c, vr, nvr, value));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    if (c == NULL) return fmi2Error;
    return STATUS(core_set(CORE_OF(c), c, vr, nvr, value));
}

/* Integer, Boolean and String variables: none (calls with nvr = 0 are fine) */
#define NO_VARIABLES(function, qualifier, type)                                                          \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, qualifier type value[]) { \
        (void)vr;                                                                                         \
        (void)value;                                                                                      \
        return nvr == 0 ? fmi2OK : not_supported(c, #function " (the FMU has Real variables only)");      \
    }
NO_VARIABLES(fmi2GetInteger, , fmi2Integer)
NO_VARIABLES(fmi2GetBoolean, , fmi2Boolean)
NO_VARIABLES(fmi2GetString, , fmi2String)
NO_VARIABLES(fmi2SetInteger, const, fmi2Integer)
NO_VARIABLES(fmi2SetBoolean, const, fmi2Boolean)
NO_VARIABLES(fmi2SetString, const, fmi2String)

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Data *copy;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    copy = core_save(CORE_OF(c), (Data *)*FMUstate);
    if (copy == NULL) return not_supported(c, "fmi2GetFMUstate (out of memory)");
    *FMUstate = (fmi2FMUstate)copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    CORE_OF(c)->data = *(const Data *)FMUstate;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi2Error;
    return STATUS(core_do_step(CORE_OF(c), c, currentCommunicationPoint, communicationStepSize));
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (c == NULL || value == NULL) return fmi2Error;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = CORE_OF(c)->data.time;
    return fmi2OK;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (c == NULL || value == NULL) return fmi2Error;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}
"""
