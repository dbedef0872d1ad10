/*
 * FMI 2.0 entry points that the ctmm FMUs do not support (ctmm): serialisation, directional derivatives
 * and the co-simulation calls below (harmless, unused, in the model-exchange lag_filter_me).
 *
 * One source shared by the shipped controller FMUs (controllers/fmu/pd_controller, pi_controller,
 * lag_filter_me: a link in their sources/) and by every FMI 2.0 plant FMU that ctmm.export_fmu writes
 * (copied into its sources/).  The standard requires every function to be exported; these report through the FMU's
 * own logger, ctmm_fmi2_not_supported(c, "<function> (why)") defined in its main source, which logs
 * "<function> is not supported by this FMU" and returns fmi2Error.  Status queries of kinds the FMU
 * does not have return fmi2Discard.
 */
#include <stddef.h>

#include "fmi2Functions.h"

#if defined(__GNUC__)
__attribute__((visibility("hidden")))   /* not an exported symbol of the FMU's binary */
#endif
fmi2Status ctmm_fmi2_not_supported(fmi2Component c, const char *function);

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    (void)size;
    return ctmm_fmi2_not_supported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return ctmm_fmi2_not_supported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return ctmm_fmi2_not_supported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return ctmm_fmi2_not_supported(c, "fmi2GetDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return ctmm_fmi2_not_supported(c, "fmi2SetRealInputDerivatives (inputs are held over a communication step)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return ctmm_fmi2_not_supported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return ctmm_fmi2_not_supported(c, "fmi2CancelStep (doStep is synchronous)");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return ctmm_fmi2_not_supported(c, "fmi2GetStatus (doStep never returns fmi2Pending)");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}
