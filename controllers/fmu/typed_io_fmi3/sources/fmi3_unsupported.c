/*
 * FMI 3.0 entry points that controllers/fmu/typed_io_fmi3 does not provide (ctmm): the variable types
 * it does not have.  The calls no ctmm FMU supports are in the shared unsupported_fmi3.c (a link to
 * controllers/fmu_common).
 *
 * The standard requires every function to be exported; these report fmi3Error (fmi3OK for an empty
 * call).  Compiled together with typed_io_fmi3.c and unsupported_fmi3.c as listed in
 * sources/buildDescription.xml.
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

