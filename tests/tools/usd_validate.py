"""UsdValidation's errors on each stage given (every registered validator, as the tests run it)."""
import sys

from pxr import Usd, UsdValidation

from csm_assets.formats.usd import register_shader_definitions

register_shader_definitions()   # Sdr knows CsmConeStepSurface, so ShaderSdrCompliance can check it
validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
failed = False
for path in sys.argv[1:]:
    errors = [e for e in UsdValidation.ValidationContext(validators).Validate(Usd.Stage.Open(path))
              if e.GetType() == UsdValidation.ValidationErrorType.Error]
    for e in errors:
        print(f"{path}: {e.GetName()}: {e.GetMessage()}")
    print(f"{path}: {len(errors)} error(s)")
    failed |= bool(errors)
sys.exit(1 if failed else 0)
